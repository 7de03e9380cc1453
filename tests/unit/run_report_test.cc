// shoal run's judgement of its log (launcher/run_report.cc) for a run that was
// interrupted: the part it never ran is not called lost, what the log lacks of the part
// that ran is. The log is shoal sim's, cut as an interruption and a lost state cut it.
#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>

#include <cstdlib>
#include <string>

#include <shoal/vehicle_state_t.hpp>

#include "analysis/sim_report.h"
#include "launcher/run_report.h"
#include "scenario/loader.h"

namespace shoal {
namespace {

std::string Tmp(const std::string& name) {
  const std::string dir = std::string(SHOAL_BINARY_DIR) + "/test_tmp";
  std::system(("mkdir -p " + dir).c_str());
  return dir + "/run_report_" + name;
}

/// A 4-s Example 2 log without vehicle 2's state at 1 s and without any state after 3 s.
std::string CutLog(const Scenario& s) {
  SimRunOptions opt;
  opt.out = Tmp("whole.lcmlog");
  SimReport report;
  std::string error;
  EXPECT_TRUE(RunSimulation(s, opt, &report, &error)) << error;
  const std::string cut = Tmp("cut.lcmlog");
  lcm::LogFile in(opt.out, "r"), out(cut, "w");
  EXPECT_TRUE(in.good() && out.good());
  while (const lcm::LogEvent* ev = in.readNextEvent()) {
    if (ev->channel.rfind("SHOAL_STATE_", 0) == 0) {
      shoal::vehicle_state_t m{};
      EXPECT_GE(m.decode(ev->data, 0, ev->datalen), 0);
      if (m.utime > 3'000'000 || (m.vehicle_id == 2 && m.utime == 1'000'000)) continue;
    }
    EXPECT_EQ(out.writeEvent(const_cast<lcm::LogEvent*>(ev)), 0);
  }
  return cut;
}

bool Says(const RunReport& r, const std::string& text) {
  for (const std::string& p : r.log_problems) {
    if (p.find(text) != std::string::npos) return true;
  }
  return false;
}

TEST(RunReport, AnInterruptedRunLostOnlyWhatIsMissingBeforeEachVehiclesLastState) {
  Scenario s = LoadScenario(std::string(SHOAL_SOURCE_DIR) + "/scenarios/paper_example2.toml");
  s.duration_s = 4.0;
  LaunchResult launch;
  launch.mode = "lockstep";
  launch.log = CutLog(s);
  launch.duration_s = 4.0;
  launch.interrupted = true;
  const RunReport stopped = MakeRunReport(s, launch);
  EXPECT_FALSE(stopped.log_complete);
  EXPECT_EQ(stopped.states_lost_before_interruption, 1);
  // 6 vehicles, ticks 0 .. 3 s: 151 each, one lost; of 201 each in the whole run.
  EXPECT_TRUE(Says(stopped, "the run was interrupted: the log holds 905 of the 1206 vehicle "
                            "states of the whole run")) << ::testing::PrintToString(stopped.log_problems);
  EXPECT_TRUE(Says(stopped, "the log lost 1 vehicle states of the part that ran"))
      << ::testing::PrintToString(stopped.log_problems);
  EXPECT_FALSE(Says(stopped, " lost (")) << ::testing::PrintToString(stopped.log_problems);

  // The same log from a run that was not interrupted lost all it lacks.
  launch.interrupted = false;
  const RunReport ended = MakeRunReport(s, launch);
  EXPECT_EQ(ended.states_lost_before_interruption, 0);
  EXPECT_TRUE(Says(ended, "the log holds 905 of 1206 vehicle states: 301 lost ("))
      << ::testing::PrintToString(ended.log_problems);
}

}  // namespace
}  // namespace shoal

// The soak analysis (analysis/soak_analysis.h) on real lockstep shoal runs: Example 2
// with a constant delay stepped by a channel event from within the exact delay margin
// (0.3435 s, docs/reference.md) to beyond it and back; the phase beyond the margin fails
// for not re-converging, the others pass; resources.csv samples every process;
// per-minute rows count the log's states exactly; a vehicle killed mid-run fails the
// verdict naming it.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "analysis/soak_analysis.h"
#include "runtime/log_reader.h"
#include "tests/integration/test_util.h"

namespace shoal {
namespace {

using shoal::testing::ParseJson;
using shoal::testing::ReadFile;
using shoal::testing::RunShoal;
using shoal::testing::SourcePath;
using shoal::testing::StartShoal;
using shoal::testing::TmpPath;
using shoal::testing::WaitExit;

constexpr double kPhaseS = 120.0;

// Example 2 with a constant 0.1 s delay, 0.5 s (beyond the margin) in [120, 240) s.
std::string WriteScenario() {
  std::string text = ReadFile(SourcePath("scenarios/paper_example2.toml"));
  const std::string from = "model = \"sinusoid\"            # tau(t) = 0.1 + 0.05 cos(t)";
  const std::size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos);
  text.replace(at, from.size(), "model = \"constant\"");
  for (const char* key : {"amplitude_s = 0.05\n", "omega_rad_s = 1.0\n"}) {
    const std::size_t k = text.find(key);
    EXPECT_NE(k, std::string::npos);
    text.erase(k, std::string(key).size());
  }
  text += "\n[[event]]\nat_s = 120\nuntil_s = 240\nkind = \"channel\"\n"
          "delay = { model = \"constant\", base_s = 0.5 }\n";
  const std::string path = TmpPath("soak_phases.toml");
  std::ofstream(path) << text;
  return path;
}

std::vector<SoakPhase> Phases() {
  return {{0, kPhaseS, "channel.delay.base_s = 0.1"},
          {kPhaseS, 2 * kPhaseS, "channel.delay.base_s = 0.5"},
          {2 * kPhaseS, 3 * kPhaseS, "channel.delay.base_s = 0.1"}};
}

struct SoakRun {
  std::string log;
  nlohmann::json report;
  SoakResult result;
};

// The lockstep run of the phase scenario, analysed once for the tests that share it.
const SoakRun& PhaseRun() {
  static SoakRun run = [] {
    SoakRun r;
    r.log = TmpPath("soak_phases.lcmlog");
    const auto out = RunShoal("run " + WriteScenario() + " --duration 360 --json --quiet "
                              "--resource-interval 30 --out " + r.log, "soak_phases");
    r.report = nlohmann::json::parse(out.out, nullptr, false);
    SoakInput in;
    in.log = r.log;
    in.key_file = r.log + ".key";
    in.resources_csv = r.log + ".d/resources.csv";
    in.report = r.report;
    in.phases = Phases();
    in.settle_s = 90;
    in.targets.memory_growth_max = 0.25;
    std::string error;
    EXPECT_TRUE(ParseSoakCriteria(nlohmann::json::parse(R"({"max_position_error_m": {"max": 2}})"),
                                  &in.criteria, &error)) << error;
    EXPECT_TRUE(AnalyseSoak(in, &r.result, &error)) << error;
    std::printf("%s\n", SoakJson(r.result).dump(1).substr(0, 6000).c_str());
    return r;
  }();
  return run;
}

TEST(Soak, PhaseBeyondTheDelayMarginFailsAndTheOthersPass) {
  const SoakRun& r = PhaseRun();
  ASSERT_TRUE(r.report.is_object());
  EXPECT_EQ(r.report["all_processes_ok"], true) << r.report;
  const SoakResult& s = r.result;
  ASSERT_EQ(s.phases.size(), 3u);
  EXPECT_TRUE(s.phases[0].pass) << SoakJson(s).dump(1);
  EXPECT_EQ(s.phases[0].metrics["reconverged"], true);
  EXPECT_FALSE(s.phases[1].pass);
  EXPECT_EQ(s.phases[1].metrics["reconverged"], false);
  EXPECT_TRUE(s.phases[2].pass) << SoakJson(s).dump(1);
  EXPECT_FALSE(s.pass);
  // Every reason is phase 1's, and it says what failed with its numbers.
  ASSERT_FALSE(s.reasons.empty());
  for (const std::string& why : s.reasons) {
    EXPECT_EQ(why.rfind("phase 2 (channel.delay.base_s = 0.5, 120-240 s): ", 0), 0u) << why;
  }
  EXPECT_NE(s.reasons[0].find("did not re-converge"), std::string::npos) << s.reasons[0];
  EXPECT_NE(s.reasons[0].find("> metrics.position_tol_m 0.5 m"), std::string::npos) << s.reasons[0];
  const nlohmann::ordered_json j = SoakJson(s);
  EXPECT_EQ(j["verdict"], "fail");
  EXPECT_EQ(j["phases"][1]["value"], "channel.delay.base_s = 0.5");
  EXPECT_GT(j["phases"][1]["metrics"]["max_position_error_m"].get<double>(),
            j["phases"][2]["metrics"]["max_position_error_m"].get<double>());
}

TEST(Soak, ResourcesSampleEveryProcessWithAPlausibleRss) {
  const SoakRun& r = PhaseRun();
  std::ifstream in(r.log + ".d/resources.csv");
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line,
            "sim_time_s,wall_time_s,process,pid,rss_kib,cpu_s,voluntary_ctxsw,involuntary_ctxsw");
  std::map<std::string, int> rows;
  std::map<std::string, double> last_sim;
  std::map<std::string, long long> last_switches;
  std::map<std::string, double> last_cpu;
  int finer_than_ticks = 0;  // CPU times that are not whole clock ticks (10 ms)
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::string sim, wall, name, pid, rss, cpu, voluntary, involuntary;
    std::getline(ss, sim, ',');
    std::getline(ss, wall, ',');
    std::getline(ss, name, ',');
    std::getline(ss, pid, ',');
    std::getline(ss, rss, ',');
    std::getline(ss, cpu, ',');
    std::getline(ss, voluntary, ',');
    std::getline(ss, involuntary, ',');
    ++rows[name];
    last_sim[name] = std::stod(sim);
    last_switches[name] = std::stoll(voluntary);
    EXPECT_GE(std::stoll(involuntary), 0) << line;
    EXPECT_GT(std::stod(rss), 500.0) << line;      // KiB: a process, not nothing
    EXPECT_LT(std::stod(rss), 2000000.0) << line;  // and not 2 GiB
    EXPECT_GE(std::stod(cpu), 0.0) << line;
    EXPECT_GE(std::stod(cpu), last_cpu[name]) << line;  // one pid per name in this run
    last_cpu[name] = std::stod(cpu);
    const double centis = std::stod(cpu) * 100.0;
    finer_than_ticks += std::fabs(centis - std::round(centis)) > 1e-3;
  }
  // The process's CPU clock, to the microsecond: nearly every sample of a process that ran
  // at all falls between clock ticks.
  EXPECT_GT(finer_than_ticks, 50);
  const std::set<std::string> expected = {"lcm-logger", "channel emulator", "leader",
                                          "vehicle 1", "vehicle 2", "vehicle 3",
                                          "vehicle 4", "vehicle 5"};
  for (const std::string& name : expected) {
    // Every 30 s of 360 (0 included): 12 samples at least.
    EXPECT_GE(rows[name], 12) << name;
  }
  EXPECT_EQ(rows.size(), expected.size());
  // The run's processes end with its final tick, before the end's sample; lcm-logger,
  // stopped last, is in it.
  for (const std::string& name : expected) EXPECT_GE(last_sim[name], 330.0) << name;
  // Every process sleeps between its messages or ticks, so its threads have switched out
  // of their own accord many times by the end.
  for (const std::string& name : expected) EXPECT_GT(last_switches[name], 100) << name;
  EXPECT_GE(last_sim["lcm-logger"], 359.0);
  ASSERT_EQ(r.result.processes.size(), expected.size());
  for (const SoakProcessGrowth& g : r.result.processes) {
    EXPECT_GT(g.rss_first_phase_kib, 500.0) << g.name;
    EXPECT_GE(g.rss_max_after_kib, g.rss_first_phase_kib) << g.name;
  }
}

TEST(Soak, MinuteRowsCountTheStatesTheLogHolds) {
  const SoakRun& r = PhaseRun();
  const SoakResult& s = r.result;
  ASSERT_EQ(s.minutes.size(), 6u);
  long long states = 0, expected = 0;
  for (const SoakMinute& m : s.minutes) {
    EXPECT_EQ(m.states, m.states_expected) << "minute " << m.minute;
    // 50 Hz, 6 vehicles: 3000 ticks a minute (the last minute has the final tick too).
    EXPECT_EQ(m.states_expected, 6 * (3000 + (m.minute == 5 ? 1 : 0))) << m.minute;
    states += m.states;
    expected += m.states_expected;
    ASSERT_TRUE(m.worst_position_error_m.has_value());
    EXPECT_EQ(m.processes.size(), 8u);
  }
  EXPECT_EQ(states, r.report["log_states"].get<long long>());
  EXPECT_EQ(expected, r.report["log_states_expected"].get<long long>());
  // Lockstep delivers at the first tick after send + tau: the error is within a period.
  ASSERT_TRUE(s.minutes[0].delay_error_p99_s.has_value());
  EXPECT_GE(*s.minutes[0].delay_error_p99_s, 0.0);
  EXPECT_LT(*s.minutes[0].delay_error_p99_s, 0.02);
}

TEST(Soak, KilledVehicleFailsTheVerdictNamingIt) {
  const std::string log = TmpPath("soak_killed.lcmlog"), out = TmpPath("soak_killed.out");
  std::remove(log.c_str());
  const pid_t run = StartShoal("run " + SourcePath("scenarios/paper_example2.toml") +
                                   " --duration 120 --json --quiet --out " + log, out);
  // Vehicle 2's process, once the log holds 10 s of the mission.
  pid_t victim = -1;
  const auto t0 = std::chrono::steady_clock::now();
  while (victim < 0 && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(30)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    int states = 0;
    LogTail tail(log);
    tail.Poll([&](const std::string& ch, const void*, int) {
      states += ch.rfind("SHOAL_STATE_", 0) == 0;
    });
    if (states < 6 * 500) continue;
    const std::string pids = ReadFile(log + ".d/resources.csv");
    std::stringstream ss(pids);
    std::string line;
    while (std::getline(ss, line)) {
      const std::size_t at = line.find(",vehicle 2,");
      if (at != std::string::npos) victim = std::atoi(line.c_str() + at + 11);
    }
  }
  ASSERT_GT(victim, 0) << ReadFile(out);
  kill(victim, SIGKILL);
  EXPECT_EQ(WaitExit(run, 30, nullptr), 1);
  SoakInput in;
  in.log = log;
  in.resources_csv = log + ".d/resources.csv";
  in.report = nlohmann::json::parse(ReadFile(out), nullptr, false);
  in.phases = {{0, 60, "first"}, {60, 120, "second"}};
  in.settle_s = 30;
  SoakResult s;
  std::string error;
  ASSERT_TRUE(AnalyseSoak(in, &s, &error)) << error;
  EXPECT_FALSE(s.pass);
  ASSERT_FALSE(s.reasons.empty());
  const std::string& first = s.reasons[0];
  EXPECT_EQ(first.rfind("a process failed", 0), 0u) << first;
  EXPECT_NE(first.find("vehicle 2 (pid " + std::to_string(victim) + ") killed by signal 9"),
            std::string::npos) << first;
  EXPECT_EQ(SoakJson(s)["verdict"], "fail");
}

}  // namespace
}  // namespace shoal

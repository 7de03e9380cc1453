// The acoustic and trace delay models, Gilbert-Elliott loss and the modem rate limit in
// the multi-process SIL runtime: a lockstep run equals shoal sim state by state, and the
// logs carry the same channel decisions (the emulator and shoal sim run one core Channel,
// positions included).
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "tests/integration/test_util.h"

namespace shoal {
namespace {

using shoal::testing::ParseJson;
using shoal::testing::ReadFile;
using shoal::testing::RunShoal;
using shoal::testing::SourcePath;
using shoal::testing::TmpPath;

std::string Url(int port) {
  return "udpm://239.255.76.67:" + std::to_string(port) + "?ttl=0&recv_buf_size=4194304";
}

// Runs `scenario` for `seconds` with shoal sim and in lockstep and compares the logs:
// no difference at all, and the same channel counts (every decision is logged).
void ExpectLockstepEqualsSim(const std::string& scenario, const std::string& tag, int port,
                             int seconds, bool modems = true) {
  const std::string sim_log = TmpPath(tag + "_sim.lcmlog"), run_log = TmpPath(tag + "_run.lcmlog");
  const std::string duration = " --duration " + std::to_string(seconds);
  const auto sim = RunShoal("sim " + scenario + duration + " --out " + sim_log, tag + "_sim");
  ASSERT_TRUE(sim.status == 0 || sim.status == 1) << sim.out << sim.err;
  const auto run = RunShoal("run " + scenario + duration + " --json --out " + run_log +
                                " --lcm-url '" + Url(port) + "'",
                            tag + "_run");
  ASSERT_EQ(run.status, sim.status) << run.out << run.err;
  EXPECT_EQ(ParseJson(run.out)["all_processes_ok"], true) << run.out;
  const auto cmp = RunShoal("compare " + run_log + " " + sim_log + " --allow-missing --json",
                            tag + "_cmp");
  ASSERT_EQ(cmp.status, 0) << cmp.out << cmp.err;
  const auto cj = ParseJson(cmp.out);
  EXPECT_EQ(cj["max_position_diff_m"].get<double>(), 0.0) << cmp.out;
  EXPECT_EQ(cj["max_velocity_diff_mps"].get<double>(), 0.0) << cmp.out;
  EXPECT_GE(cj["samples"].get<double>(), 0.9 * 5.0 * (seconds * 50 + 1)) << cmp.out;
  // With the scenario file, so that a trace is found (the log holds only the TOML) and
  // every delay is checked against the model: exactly for a trace, within the bounds
  // for acoustic.
  const std::string with = " --json --scenario " + scenario;
  const auto a = ParseJson(RunShoal("analyze " + sim_log + with, tag + "_as").out);
  const auto b = ParseJson(RunShoal("analyze " + run_log + with, tag + "_ar").out);
  for (const char* key : {"delivered", "dropped", "dropped_loss", "dropped_range",
                          "skipped_modem_busy", "model_mismatches"}) {
    EXPECT_EQ(a["channel"][key], b["channel"][key]) << key;
  }
  EXPECT_EQ(a["channel"]["model_mismatches"], 0);
  EXPECT_EQ(a["channel"]["unknown_link_events"], 0);
  EXPECT_GT(a["channel"]["delivered"].get<double>(), 0.0);
  if (modems) {
    EXPECT_GT(a["channel"]["skipped_modem_busy"].get<double>(), 0.0);
  }
}

// scenarios/acoustic_survey.toml: acoustic delays from the vehicles' ranges, range losses,
// Gilbert-Elliott bursts and one state per second per modem.
TEST(SilChannelModels, AcousticSurveyLockstepEqualsShoalSim) {
  ExpectLockstepEqualsSim(SourcePath("scenarios/acoustic_survey.toml"), "sil_acoustic", 31511,
                          20);
}

// A trace delay (relative to the scenario file, interpolated) that makes later messages
// overtake earlier ones, with the same modems.
TEST(SilChannelModels, TraceDelayLockstepEqualsShoalSim) {
  std::string text = ReadFile(SourcePath("scenarios/acoustic_survey.toml"));
  const std::string from = "model = \"acoustic\"";
  const auto at = text.find(from);
  ASSERT_NE(at, std::string::npos);
  const auto end = text.find("\n[channel.loss]");
  ASSERT_NE(end, std::string::npos);
  text.replace(at, end - at, "model = \"trace\"\nfile = \"sil_trace_rows.csv\"\n");
  std::ofstream(TmpPath("sil_trace_rows.csv"))
      << "t_s, delay_s\n0, 0.3\n2, 1.5\n2.5, 0.2\n6, 0.9\n9, 0.4\n14, 1.1\n";
  const std::string scenario = TmpPath("sil_trace.toml");
  std::ofstream(scenario) << text;
  ExpectLockstepEqualsSim(scenario, "sil_trace", 31521, 20);
}

// Every kind of timeline event, one after the other in 16 s of Example 2, among them a
// channel change to a delay shorter than [channel.delay]'s (the lockstep lookahead must
// shrink for it) and a switch to another topology: lockstep equals shoal sim exactly.
TEST(SilChannelModels, EveryEventKindLockstepEqualsShoalSim) {
  std::string text = ReadFile(SourcePath("scenarios/paper_example2.toml"));
  text += R"(
[[event]]
at_s = 2
until_s = 4
kind = "link_down"
links = [[0, 1]]

[[event]]
at_s = 4
until_s = 6
kind = "channel"
delay = { model = "constant", base_s = 0.01 }
loss = { model = "bernoulli", probability = 0.2 }

[[event]]
at_s = 6
until_s = 9
kind = "topology"
leader_links = [1]
edges = [[2, 1], [3, 2], [4, 3], [5, 4]]

[[event]]
at_s = 9
until_s = 10
kind = "vehicle_silent"
vehicles = [2]

[[event]]
at_s = 10
until_s = 11
kind = "vehicle_deaf"
vehicles = [4]

[[event]]
at_s = 11
until_s = 12
kind = "leader_silent"

[[event]]
at_s = 12
kind = "controller_reset"
vehicles = [3]
outage_s = 2
)";
  const std::string scenario = TmpPath("sil_events.toml");
  std::ofstream(scenario) << text;
  ExpectLockstepEqualsSim(scenario, "sil_events", 31531, 16, /*modems=*/false);
}

}  // namespace
}  // namespace shoal

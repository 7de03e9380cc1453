// `--set KEY=VALUE` as a user gives it to shoal sim, run and design: refusals, effect on
// the run, the log that keeps the effective scenario, the scenario design writes.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "tests/integration/test_util.h"

namespace shoal {
namespace {

using shoal::testing::ParseJson;
using shoal::testing::ReadFile;
using shoal::testing::RunShoal;
using shoal::testing::SourcePath;
using shoal::testing::TmpPath;

const std::string kExample2 = SourcePath("scenarios/paper_example2.toml");
// Random losses: the seed changes which messages are lost, hence the result.
const std::string kLossy = " --set 'channel.loss={ model = \"bernoulli\", probability = 0.3 }'";

double FinalError(const std::string& sets, const std::string& tag) {
  const auto r = RunShoal("sim " + kExample2 + " --duration 10 --json --quiet" + sets, tag);
  EXPECT_NE(r.status, 2) << r.err;
  return ParseJson(r.out)["final_position_error_m"].get<double>();
}

TEST(SetCli, SimSeedChangesTheResult) {
  const double seed2 = FinalError(kLossy + " --set run.seed=2", "set_seed2");
  const double seed3 = FinalError(kLossy + " --set run.seed=3", "set_seed3");
  EXPECT_NE(seed2, seed3);
  // The same --set, the same run.
  EXPECT_EQ(FinalError(kLossy + " --set run.seed=2", "set_seed2b"), seed2);
  // The order of the flags is that of the changes: the last one wins.
  EXPECT_EQ(FinalError(kLossy + " --set run.seed=3 --set run.seed=2", "set_seed32"), seed2);
}

TEST(SetCli, SetBeforeTheScenarioIsOneChange) {
  const auto r = RunShoal("sim --set run.seed=2 " + kExample2 + " --duration 1 --json --quiet",
                          "set_before");
  EXPECT_NE(r.status, 2) << r.err;
}

TEST(SetCli, BadSetExitsTwoNamingIt) {
  for (const std::string command : {"sim", "run", "design"}) {
    const std::string cmd = command + " " + kExample2 + " ";
    const auto syntax = RunShoal(cmd + "--set run.seed", "set_bad_syntax");
    EXPECT_EQ(syntax.status, 2) << command;
    EXPECT_NE(syntax.err.find("shoal " + command + ": --set run.seed: expected KEY=VALUE"),
              std::string::npos)
        << syntax.err;
    const auto empty = RunShoal(cmd + "--set =1", "set_bad_empty");
    EXPECT_EQ(empty.status, 2) << command;
    EXPECT_NE(empty.err.find("--set =1: empty key"), std::string::npos) << empty.err;
    const auto value = RunShoal(cmd + "--set 'control.k1=[1,'", "set_bad_value");
    EXPECT_EQ(value.status, 2) << command;
    EXPECT_NE(value.err.find("--set control.k1=[1,: not a TOML value"), std::string::npos)
        << value.err;
    const auto index = RunShoal(cmd + "--set follower[9].pitch_rad=0", "set_bad_index");
    EXPECT_EQ(index.status, 2) << command;
    EXPECT_NE(index.err.find("--set follower[9].pitch_rad=0: follower[9]: index past the end"),
              std::string::npos)
        << index.err;
    const auto invalid = RunShoal(cmd + "--set channel.delay.base_s=-1", "set_bad_invalid");
    EXPECT_EQ(invalid.status, 2) << command;
    EXPECT_NE(invalid.err.find("shoal " + command +
                               ": --set channel.delay.base_s=-1: channel.delay.base_s: "),
              std::string::npos)
        << invalid.err;
  }
}

TEST(SetCli, TheLogKeepsTheEffectiveScenario) {
  const std::string log = TmpPath("set_effective.lcmlog");
  const auto sim = RunShoal("sim " + kExample2 + " --duration 5 --json --quiet --out " + log +
                                " --set control.k1=0.2 --set 'channel.delay={ model = "
                                "\"constant\", base_s = 0.05 }'",
                            "set_effective_sim");
  ASSERT_NE(sim.status, 2) << sim.err;
  // shoal analyze reads the scenario from the log: the changed one.
  const auto ana = RunShoal("analyze " + log + " --json", "set_effective_ana");
  ASSERT_NE(ana.status, 2) << ana.err;
  EXPECT_FALSE(ParseJson(ana.out).empty()) << ana.out;
  const std::string text = ReadFile(log);
  EXPECT_NE(text.find("#   --set control.k1=0.2"), std::string::npos);
  EXPECT_NE(text.find("constant"), std::string::npos);
}

TEST(SetCli, DesignWritesTheEffectiveScenario) {
  const std::string out = TmpPath("set_advised.toml");
  std::remove(out.c_str());
  const auto design = RunShoal("design " + kExample2 +
                                   " --set 'channel.delay={ model = \"constant\", base_s = 0.1 }'"
                                   " --write-scenario " + out + " --json",
                               "set_design");
  ASSERT_NE(design.status, 2) << design.err;
  const std::string text = ReadFile(out);
  EXPECT_NE(text.find("#   --set channel.delay={ model = \"constant\", base_s = 0.1 }"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("(shoal design --advise)"), std::string::npos) << text;
  EXPECT_NE(text.find("paper_example2_advised"), std::string::npos) << text;
  EXPECT_EQ(text.find("amplitude_s"), std::string::npos) << text;
  const auto sim = RunShoal("sim " + out + " --duration 1 --json --quiet", "set_design_sim");
  EXPECT_NE(sim.status, 2) << sim.err;
}

}  // namespace
}  // namespace shoal

// shoal run hands its --set flags to every process it starts: a lockstep SIL run with
// --set equals shoal sim with the same --set, bit for bit.
#include <gtest/gtest.h>

#include <string>

#include "tests/integration/test_util.h"

namespace shoal {
namespace {

using shoal::testing::ParseJson;
using shoal::testing::RunShoal;
using shoal::testing::SourcePath;
using shoal::testing::TmpPath;

TEST(Sil, LockstepRunWithSetEqualsShoalSimWithSet) {
  const std::string scenario = SourcePath("scenarios/paper_example2.toml");
  // Changes every process must see: the gain (vehicles), the leader's path (leader), the
  // delay model (emulator) and a follower's start (vehicle 2).
  const std::string sets =
      " --set control.k1=0.25 --set leader.path=line"
      " --set 'channel.delay={ model = \"uniform\", base_s = 0.1, amplitude_s = 0.04 }'"
      " --set follower[1].heading_rad=0.3 --set run.seed=5";
  const std::string run_log = TmpPath("set_sil_run.lcmlog"), sim_log = TmpPath("set_sil_sim.lcmlog");
  const auto run = RunShoal("run " + scenario + " --duration 10 --json --out " + run_log + sets,
                            "set_sil_run");
  ASSERT_NE(run.status, 2) << run.out << run.err;
  EXPECT_EQ(ParseJson(run.out)["all_processes_ok"], true) << run.out;
  const auto sim = RunShoal("sim " + scenario + " --duration 10 --json --out " + sim_log + sets,
                            "set_sil_sim");
  ASSERT_NE(sim.status, 2) << sim.err;
  const auto cmp = RunShoal("compare " + run_log + " " + sim_log + " --allow-missing --json",
                            "set_sil_cmp");
  ASSERT_EQ(cmp.status, 0) << cmp.out << cmp.err;
  const auto cj = ParseJson(cmp.out);
  EXPECT_LE(cj["max_position_diff_m"].get<double>(), 1e-9) << cmp.out;
  EXPECT_GE(cj["samples"].get<double>(), 0.9 * 6.0 * (10 * 50 + 1)) << cmp.out;
  EXPECT_EQ(ParseJson(run.out)["final_position_error_m"].get<double>(),
            ParseJson(sim.out)["final_position_error_m"].get<double>());
  // Without the changes the run differs: the comparison above can fail.
  const auto plain = RunShoal("sim " + scenario + " --duration 10 --json", "set_sil_plain");
  EXPECT_NE(ParseJson(plain.out)["final_position_error_m"].get<double>(),
            ParseJson(sim.out)["final_position_error_m"].get<double>());
}

}  // namespace
}  // namespace shoal

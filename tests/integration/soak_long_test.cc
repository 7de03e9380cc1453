// The example soak of docs/campaigns.md, run as a user runs it: two hours of mission time
// in lockstep (about two minutes of machine time), so it is in `make test-long`, not in
// the default test pass.
#include <cstdlib>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tests/integration/test_util.h"

namespace shoal::testing {
namespace {

using ojson = nlohmann::ordered_json;

// The example campaign: two hours of mission time, the delay stepped from 0.05 s to 0.3 s
// and back, all within Example 2's margin (0.3435 s).
TEST(SoakLong, TwoHoursOfExample2InLockstepPass) {
  const std::string dir = TmpPath("soak_cli_two_hours");
  std::system(("rm -rf " + dir).c_str());
  const RunResult r =
      RunShoal("soak " + SourcePath("campaigns/soak_delay_steps.toml") + " --out " + dir, "soak_2h");
  EXPECT_EQ(r.status, 0) << r.out << r.err;
  const ojson soak = ParseJson(ReadFile(dir + "/soak.json"));
  EXPECT_EQ(soak["verdict"], "pass") << soak["reasons"].dump();
  ASSERT_EQ(soak["phases"].size(), 12u);
  for (const ojson& p : soak["phases"]) EXPECT_TRUE(p["pass"].get<bool>()) << p.dump();
  EXPECT_EQ(soak["phases"][5]["value"], "channel.delay.base_s = 0.3");
  EXPECT_EQ(soak["phases"][11]["end_s"], 7200.0);
  EXPECT_EQ(soak["minutes"].size(), 120u);
  EXPECT_TRUE(soak["run"]["log_complete"].get<bool>());
  EXPECT_EQ(soak["run"]["restarts"].size(), 0u);
  for (const ojson& p : soak["processes"]) EXPECT_LE(p["growth"].get<double>(), 0.01) << p.dump();
  EXPECT_GT(ReadFile(dir + "/soak.png").size(), 10000u);
}

}  // namespace
}  // namespace shoal::testing

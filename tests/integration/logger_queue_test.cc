// The run's lcm-logger keeps bursts far beyond LCM's 30-message subscription queue
// (runtime/lcm_queue_shim.c, preloaded by shoal run), so that the states of many vehicles
// stepping the same tick are all logged, and lockstep windows are no longer cut to 20
// logger messages (docs/run.md, "The logger's queue").
#include <cstdio>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "runtime/lcm_bus.h"
#include "tests/integration/test_util.h"

namespace shoal {
namespace {

using testing::ParseJson;
using testing::ReadFile;
using testing::RunShoal;
using testing::SourcePath;
using testing::TmpPath;

int ProbeKept(const std::string& preload, int burst) {
  const std::string url = PrivateLcmUrl(RandomPrivatePort(1));
  const std::string cmd = (preload.empty() ? "" : "LD_PRELOAD=" + preload + " ") +
                          std::string(SHOAL_BINARY_DIR) + "/tests/lcm_queue_probe '" + url +
                          "' " + std::to_string(burst);
  FILE* p = popen(cmd.c_str(), "r");
  if (p == nullptr) return -1;
  int kept = -1;
  if (std::fscanf(p, "%d", &kept) != 1) kept = -1;
  pclose(p);
  return kept;
}

TEST(LoggerQueue, ThePreloadedLibraryKeepsABurstThatLcmsQueueDrops) {
  const std::string shim = std::string(SHOAL_BINARY_DIR) + "/runtime/libshoal_lcm_queue.so";
  const int burst = 400;
  // Without the library LCM keeps its queue of 30 (plus the one being dispatched).
  const int plain = ProbeKept("", burst);
  ASSERT_GT(plain, 0);
  EXPECT_LE(plain, 31);
  EXPECT_EQ(ProbeKept(shim, burst), burst);
}

TEST(LoggerQueue, FortyFollowersInLockstepLogEveryStateInWindowsOfTheChannelsLag) {
  const std::string scenario = TmpPath("logger_queue_40.toml");
  ASSERT_EQ(std::system(("'" + SourcePath("bench/scale_scenario.sh") + "' 40 4 > '" +
                         scenario + "'").c_str()),
            0);
  const std::string log = TmpPath("logger_queue_40.lcmlog");
  const auto r = RunShoal("run '" + scenario + "' --out '" + log + "' --json",
                          "logger_queue_40");
  ASSERT_LE(r.status, 1) << r.err;  // 1: 4 s do not let the chain converge
  const auto j = ParseJson(r.out);
  EXPECT_EQ(j["log_complete"], true) << r.out;
  EXPECT_EQ(j["log_states"], j["log_states_expected"]) << r.out;
  // The delay's smallest value (0.05 s, 2.5 periods) alone bounds the window: 41 vehicles'
  // states per tick would cut it to 1 tick with LCM's queue of 30.
  EXPECT_NE(ReadFile(log + ".d/emulator.txt").find("lockstep, 3 tick(s) per round trip"),
            std::string::npos)
      << ReadFile(log + ".d/emulator.txt");
}

}  // namespace
}  // namespace shoal

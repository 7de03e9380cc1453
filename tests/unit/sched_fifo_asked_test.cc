// Which processes of a run are asked for SCHED_FIFO: shoal run's --sched-fifo and the
// SHOAL_SCHED_FIFO the processes inherit, whichever asks for more; none in lockstep.
#include <gtest/gtest.h>

#include "launcher/launcher.h"

namespace shoal {
namespace {

TEST(SchedFifoAsked, TheOptionOrTheEnvironmentWhicheverAsksForMore) {
  const Mode rt = Mode::kRealtime;
  EXPECT_EQ(SchedFifoAsked(rt, "", nullptr), "none");
  EXPECT_EQ(SchedFifoAsked(rt, "all", nullptr), "all");
  EXPECT_EQ(SchedFifoAsked(rt, "emulator", nullptr), "emulator");
  EXPECT_EQ(SchedFifoAsked(rt, "", "1"), "all");
  EXPECT_EQ(SchedFifoAsked(rt, "", "emulator"), "emulator");
  EXPECT_EQ(SchedFifoAsked(rt, "emulator", "1"), "all");
  EXPECT_EQ(SchedFifoAsked(rt, "all", "emulator"), "all");
}

TEST(SchedFifoAsked, NoneInLockstep) {
  EXPECT_EQ(SchedFifoAsked(Mode::kLockstep, "", "1"), "none");
  EXPECT_EQ(SchedFifoAsked(Mode::kLockstep, "", "emulator"), "none");
}

}  // namespace
}  // namespace shoal

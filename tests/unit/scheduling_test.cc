// Real-time scheduling as SHOAL_SCHED_FIFO asks: unset, no process takes SCHED_FIFO;
// "emulator", the channel emulator (the clock master) alone; any other value, every
// real-time process. Each case runs in a child process, whose policy it changes.
#include <sched.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <string>

#include <gtest/gtest.h>

#include "runtime/process.h"

namespace shoal {
namespace {

// The policy a process gets from EnableRealtimeScheduling with SHOAL_SCHED_FIFO = `value`
// (nullptr: unset), and what the function said.
struct Got {
  int policy = -1;
  std::string said;
};

Got PolicyWith(const char* value, bool clock_master) {
  int fds[2];
  if (pipe(fds) != 0) return {};
  const pid_t pid = fork();
  if (pid == 0) {
    close(fds[0]);
    if (value == nullptr) {
      unsetenv("SHOAL_SCHED_FIFO");
    } else {
      setenv("SHOAL_SCHED_FIFO", value, 1);
    }
    const std::string said = EnableRealtimeScheduling(clock_master ? 50 : 40, clock_master);
    const std::string out = std::to_string(sched_getscheduler(0)) + " " + said;
    _exit(write(fds[1], out.data(), out.size()) == static_cast<ssize_t>(out.size()) ? 0 : 1);
  }
  close(fds[1]);
  std::string out;
  char buf[256];
  for (ssize_t n; (n = read(fds[0], buf, sizeof(buf))) > 0;) out.append(buf, n);
  close(fds[0]);
  waitpid(pid, nullptr, 0);
  Got g;
  const std::size_t space = out.find(' ');
  if (space == std::string::npos) return g;
  g.policy = std::stoi(out.substr(0, space));
  g.said = out.substr(space + 1);
  return g;
}

TEST(RealtimeScheduling, UnsetLeavesEveryProcessUnderTheDefaultPolicy) {
  for (const bool master : {false, true}) {
    const Got g = PolicyWith(nullptr, master);
    EXPECT_EQ(g.policy, SCHED_OTHER) << g.said;
    EXPECT_EQ(g.said, "SCHED_OTHER, timer slack 1 ns");
  }
}

TEST(RealtimeScheduling, EmulatorGivesTheClockMasterAloneSchedFifo) {
  const Got node = PolicyWith("emulator", false);
  EXPECT_EQ(node.policy, SCHED_OTHER) << node.said;
  EXPECT_EQ(node.said, "SCHED_OTHER, timer slack 1 ns");
  const Got master = PolicyWith("emulator", true);
  if (geteuid() != 0) {
    EXPECT_NE(master.said.find("SCHED_FIFO refused"), std::string::npos) << master.said;
    GTEST_SKIP() << "SCHED_FIFO needs root";
  }
  EXPECT_EQ(master.policy, SCHED_FIFO) << master.said;
  EXPECT_EQ(master.said, "SCHED_FIFO priority 50, timer slack 1 ns");
}

TEST(RealtimeScheduling, AnyOtherValueGivesEveryRealTimeProcessSchedFifo) {
  if (geteuid() != 0) GTEST_SKIP() << "SCHED_FIFO needs root";
  for (const bool master : {false, true}) {
    const Got g = PolicyWith("1", master);
    EXPECT_EQ(g.policy, SCHED_FIFO) << g.said;
    EXPECT_EQ(g.said, std::string("SCHED_FIFO priority ") + (master ? "50" : "40") +
                          ", timer slack 1 ns");
  }
}

}  // namespace
}  // namespace shoal

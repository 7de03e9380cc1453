// Real-time scheduling as SHOAL_SCHED_FIFO asks: unset, no process takes SCHED_FIFO;
// "emulator", the channel emulator (the clock master) alone; any other value, every
// real-time process. A process's --sched-fifo asks for it, and a refusal then stops the
// process. Each case runs in a child process, whose policy it changes.
#include <sched.h>
#include <sys/resource.h>
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

// In a child: EnableRealtimeScheduling required by the command line, after giving up the
// right to SCHED_FIFO when `unprivileged` (RLIMIT_RTPRIO 0, and as root, the user nobody);
// then the policy, whether it was refused, SchedFifoPermitted's answer, and what was said.
struct Required {
  int policy = -1;
  bool refused = false;
  bool permitted = false;
  std::string said;
};

Required RequiredFifo(bool unprivileged) {
  int fds[2];
  if (pipe(fds) != 0) return {};
  const pid_t pid = fork();
  if (pid == 0) {
    close(fds[0]);
    unsetenv("SHOAL_SCHED_FIFO");
    if (unprivileged) {
      const rlimit none = {0, 0};
      if (setrlimit(RLIMIT_RTPRIO, &none) != 0) _exit(3);
      if (geteuid() == 0 && (setresgid(65534, 65534, 65534) != 0 ||
                             setresuid(65534, 65534, 65534) != 0)) {
        _exit(3);
      }
    }
    std::string why;
    const bool permitted = SchedFifoPermitted(kEmulatorFifoPriority, &why);
    bool refused = false;
    const std::string said = EnableRealtimeScheduling(kNodeFifoPriority, false, true, &refused);
    const std::string out = std::to_string(sched_getscheduler(0)) + " " + (refused ? "1" : "0") +
                            (permitted ? "1" : "0") + " " + said + " | " + why;
    _exit(write(fds[1], out.data(), out.size()) == static_cast<ssize_t>(out.size()) ? 0 : 1);
  }
  close(fds[1]);
  std::string out;
  char buf[512];
  for (ssize_t n; (n = read(fds[0], buf, sizeof(buf))) > 0;) out.append(buf, n);
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  Required r;
  const std::size_t space = out.find(' ');
  if (space == std::string::npos || out.size() < space + 4) return r;
  r.policy = std::stoi(out.substr(0, space));
  r.refused = out[space + 1] == '1';
  r.permitted = out[space + 2] == '1';
  r.said = out.substr(space + 4);
  return r;
}

TEST(RealtimeScheduling, RequiredByTheCommandLineAndRefusedSaysSoAndWhy) {
  const Required r = RequiredFifo(/*unprivileged=*/true);
  EXPECT_EQ(r.policy, SCHED_OTHER) << r.said;
  EXPECT_TRUE(r.refused) << r.said;
  EXPECT_FALSE(r.permitted) << r.said;
  EXPECT_NE(r.said.find("SCHED_FIFO refused: Operation not permitted; it needs CAP_SYS_NICE, "
                        "which root has, or RLIMIT_RTPRIO >= 40"),
            std::string::npos)
      << r.said;
  EXPECT_NE(r.said.find("| SCHED_FIFO priority 50 refused: Operation not permitted"),
            std::string::npos)
      << r.said;
}

TEST(RealtimeScheduling, RequiredByTheCommandLineIsGivenWithoutTheEnvironment) {
  if (geteuid() != 0) GTEST_SKIP() << "SCHED_FIFO needs root";
  const Required r = RequiredFifo(/*unprivileged=*/false);
  EXPECT_EQ(r.policy, SCHED_FIFO) << r.said;
  EXPECT_FALSE(r.refused) << r.said;
  EXPECT_TRUE(r.permitted) << r.said;
  EXPECT_EQ(r.said, "SCHED_FIFO priority 40, timer slack 1 ns | ");
}

}  // namespace
}  // namespace shoal

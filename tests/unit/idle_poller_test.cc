// The idle poller: a thread per allowed CPU, pinned to it at SCHED_IDLE, only where no
// cpuidle driver turns shoal run's CPU latency request into polling.
#include <gtest/gtest.h>
#include <dirent.h>
#include <sched.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "launcher/idle_poller.h"
#include "launcher/machine_witness.h"

namespace shoal {
namespace {

struct ThreadPlace {
  int policy = -1;
  std::vector<int> cpus;
};

/// Every thread of this process: its scheduling policy (field 41 of its stat) and the CPUs
/// it may run on.
std::vector<ThreadPlace> Threads() {
  std::vector<ThreadPlace> out;
  DIR* d = opendir("/proc/self/task");
  if (d == nullptr) return out;
  while (dirent* e = readdir(d)) {
    if (e->d_name[0] == '.') continue;
    const int tid = std::atoi(e->d_name);
    std::ifstream in(std::string("/proc/self/task/") + e->d_name + "/stat");
    std::string stat((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::size_t close = stat.rfind(')');
    if (close == std::string::npos) continue;
    std::istringstream fields(stat.substr(close + 2));  // from field 3 (state) on
    std::string f;
    ThreadPlace t;
    for (int i = 3; i <= 41 && (fields >> f); ++i) {
      if (i == 41) t.policy = std::atoi(f.c_str());
    }
    cpu_set_t set;
    CPU_ZERO(&set);
    if (sched_getaffinity(tid, sizeof(set), &set) == 0) {
      for (int c = 0; c < CPU_SETSIZE; ++c) {
        if (CPU_ISSET(c, &set)) t.cpus.push_back(c);
      }
    }
    out.push_back(t);
  }
  closedir(d);
  return out;
}

TEST(IdlePoller, OnlyWithoutACpuidleDriverDoesTheRequestNotPoll) {
  EXPECT_FALSE(LatencyRequestPolls("none"));
  EXPECT_FALSE(LatencyRequestPolls(""));
  EXPECT_TRUE(LatencyRequestPolls("intel_idle"));
  EXPECT_TRUE(LatencyRequestPolls("acpi_idle"));
  EXPECT_TRUE(LatencyRequestPolls("haltpoll"));
}

TEST(IdlePoller, OneThreadPerAllowedCpuPinnedToItAtSchedIdleUntilStopped) {
  const std::vector<int> cpus = AllowedCpus();
  ASSERT_FALSE(cpus.empty());
  IdlePoller poller;
  // SCHED_IDLE and a thread's own affinity within the process's need no privilege.
  ASSERT_EQ(poller.Start(), static_cast<int>(cpus.size()));
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  std::set<int> pinned;
  int idle = 0;
  for (const ThreadPlace& t : Threads()) {
    if (t.policy != SCHED_IDLE) continue;
    ++idle;
    ASSERT_EQ(t.cpus.size(), 1u);
    pinned.insert(t.cpus[0]);
  }
  EXPECT_EQ(idle, static_cast<int>(cpus.size()));
  EXPECT_EQ(pinned, std::set<int>(cpus.begin(), cpus.end()));
  EXPECT_EQ(poller.Start(), static_cast<int>(cpus.size()));  // started once only
  EXPECT_GE(poller.Stop(), 0.0);
  int left = 0;
  for (const ThreadPlace& t : Threads()) left += t.policy == SCHED_IDLE;
  EXPECT_EQ(left, 0);
  EXPECT_EQ(poller.spinning(), 0);
}

TEST(IdlePoller, AThreadAtNormalPriorityKeepsItsCpu) {
  // The poller must take only what would be idle: a busy thread at normal priority on the
  // same CPU keeps nearly all of it. At normal priority the poller would take half.
  const std::vector<int> cpus = AllowedCpus();
  ASSERT_FALSE(cpus.empty());
  IdlePoller poller;
  ASSERT_GT(poller.Start(), 0);
  double share = 0.0;
  std::thread busy([&] {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(cpus[0], &set);
    ASSERT_EQ(pthread_setaffinity_np(pthread_self(), sizeof(set), &set), 0);
    timespec c0{}, c1{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &c0);
    const auto w0 = std::chrono::steady_clock::now();
    while (std::chrono::steady_clock::now() - w0 < std::chrono::milliseconds(300)) {
    }
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &c1);
    const double cpu = (c1.tv_sec - c0.tv_sec) + (c1.tv_nsec - c0.tv_nsec) * 1e-9;
    share = cpu / std::chrono::duration<double>(std::chrono::steady_clock::now() - w0).count();
  });
  busy.join();
  poller.Stop();
  // Other tests' processes may share the CPU too; the poller's own share is 3/1027 of it.
  EXPECT_GT(share, 0.6) << "a busy thread got " << share << " of its CPU beside the poller";
}

}  // namespace
}  // namespace shoal

// The idle poller: a thread per allowed CPU, pinned to it at SCHED_IDLE, only where no
// cpuidle driver turns shoal run's CPU latency request into polling.
#include <gtest/gtest.h>
#include <dirent.h>
#include <sched.h>

#include <chrono>
#include <iterator>
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
  int tid = 0;
  std::string name;
  int policy = -1;
  std::vector<int> cpus;
};

std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

/// Every thread of this process: its name, its scheduling policy (field 41 of its stat)
/// and the CPUs it may run on.
std::vector<ThreadPlace> Threads() {
  std::vector<ThreadPlace> out;
  DIR* d = opendir("/proc/self/task");
  if (d == nullptr) return out;
  while (dirent* e = readdir(d)) {
    if (e->d_name[0] == '.') continue;
    ThreadPlace t;
    t.tid = std::atoi(e->d_name);
    const std::string dir = std::string("/proc/self/task/") + e->d_name;
    t.name = ReadFile(dir + "/comm");
    if (!t.name.empty() && t.name.back() == '\n') t.name.pop_back();
    const std::string stat = ReadFile(dir + "/stat");
    const std::size_t close = stat.rfind(')');
    if (close == std::string::npos) continue;
    std::istringstream fields(stat.substr(close + 2));  // from field 3 (state) on
    std::string f;
    for (int i = 3; i <= 41 && (fields >> f); ++i) {
      if (i == 41) t.policy = std::atoi(f.c_str());
    }
    cpu_set_t set;
    CPU_ZERO(&set);
    if (sched_getaffinity(t.tid, sizeof(set), &set) == 0) {
      for (int c = 0; c < CPU_SETSIZE; ++c) {
        if (CPU_ISSET(c, &set)) t.cpus.push_back(c);
      }
    }
    out.push_back(t);
  }
  closedir(d);
  return out;
}

std::vector<ThreadPlace> PollerThreads() {
  std::vector<ThreadPlace> out;
  for (const ThreadPlace& t : Threads()) {
    if (t.name == kIdlePollerThreadName) out.push_back(t);
  }
  return out;
}

/// The time a thread of this process has run, in ns (the first field of its schedstat).
long long RanNs(int tid) {
  std::istringstream in(ReadFile("/proc/self/task/" + std::to_string(tid) + "/schedstat"));
  long long ns = -1;
  in >> ns;
  return ns;
}

TEST(IdlePoller, OnlyWithoutACpuidleDriverDoesTheRequestNotPoll) {
  EXPECT_FALSE(LatencyRequestPolls("none", ""));
  EXPECT_FALSE(LatencyRequestPolls("", ""));
  EXPECT_TRUE(LatencyRequestPolls("intel_idle", "POLL"));
  EXPECT_TRUE(LatencyRequestPolls("acpi_idle", "POLL"));
  EXPECT_TRUE(LatencyRequestPolls("haltpoll", "POLL"));
  EXPECT_TRUE(LatencyRequestPolls("haltpoll", ""));
  EXPECT_FALSE(LatencyRequestPolls("psci_idle", "WFI"));
}

TEST(IdlePoller, OneThreadPerAllowedCpuPinnedToItAtSchedIdleUntilStopped) {
  const std::vector<int> cpus = AllowedCpus();
  ASSERT_FALSE(cpus.empty());
  IdlePoller poller;
  // SCHED_IDLE and a thread's own affinity within the process's need no privilege.
  ASSERT_EQ(poller.Start(), static_cast<int>(cpus.size()));
  std::set<int> pinned;
  const std::vector<ThreadPlace> threads = PollerThreads();
  for (const ThreadPlace& t : threads) {
    EXPECT_EQ(t.policy, SCHED_IDLE);
    ASSERT_EQ(t.cpus.size(), 1u);
    pinned.insert(t.cpus[0]);
  }
  EXPECT_EQ(threads.size(), cpus.size());
  EXPECT_EQ(pinned, std::set<int>(cpus.begin(), cpus.end()));
  // They spin: each runs while this thread sleeps.
  std::vector<long long> before;
  for (const ThreadPlace& t : threads) before.push_back(RanNs(t.tid));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  for (std::size_t i = 0; i < threads.size(); ++i) {
    EXPECT_GT(RanNs(threads[i].tid), before[i]) << "the thread on CPU " << threads[i].cpus[0];
  }
  EXPECT_EQ(poller.Start(), static_cast<int>(cpus.size()));  // started once only
  EXPECT_GT(poller.Stop(), 0.0);
  EXPECT_TRUE(PollerThreads().empty());
  EXPECT_EQ(poller.spinning(), 0);
}

TEST(IdlePoller, AThreadOfTheSameGroupTakesTheCpuFromIt) {
  // Beside a busy thread of this process on the same CPU the poller runs only what its
  // SCHED_IDLE weight gives it (3 against 1024); at normal priority it would run as much
  // as the busy thread. Compared over the same time, so other load changes both alike.
  const std::vector<int> cpus = AllowedCpus();
  ASSERT_FALSE(cpus.empty());
  IdlePoller poller;
  ASSERT_GT(poller.Start(), 0);
  int spinner = 0;
  for (const ThreadPlace& t : PollerThreads()) {
    if (t.cpus.size() == 1 && t.cpus[0] == cpus[0]) spinner = t.tid;
  }
  ASSERT_NE(spinner, 0) << "no poller thread on CPU " << cpus[0];
  long long busy_ns = 0, spinner_ns = 0;
  std::thread busy([&] {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(cpus[0], &set);
    ASSERT_EQ(pthread_setaffinity_np(pthread_self(), sizeof(set), &set), 0);
    const long long s0 = RanNs(spinner);
    timespec c0{}, c1{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &c0);
    const auto w0 = std::chrono::steady_clock::now();
    while (std::chrono::steady_clock::now() - w0 < std::chrono::milliseconds(300)) {
    }
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &c1);
    spinner_ns = RanNs(spinner) - s0;
    busy_ns = (c1.tv_sec - c0.tv_sec) * 1000000000LL + (c1.tv_nsec - c0.tv_nsec);
  });
  busy.join();
  poller.Stop();
  ASSERT_GT(busy_ns, 0);
  EXPECT_LT(spinner_ns, busy_ns / 10) << "the poller ran " << spinner_ns << " ns beside "
                                      << busy_ns << " ns of a busy thread";
}

}  // namespace
}  // namespace shoal

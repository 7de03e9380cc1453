#include "launcher/idle_poller.h"

#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <time.h>

#include <fstream>
#include <sstream>
#include <system_error>

#include "launcher/machine_witness.h"

namespace shoal {
namespace {

std::string FirstWord(const std::string& path) {
  std::ifstream in(path);
  std::string word;
  if (!(in >> word)) return "";
  return word;
}

/// Whether the cgroup at `dir` (a directory under /sys/fs/cgroup) or one above it, up to
/// `root`, limits CPU time: cgroup v2's cpu.max "QUOTA PERIOD" rather than "max PERIOD", or
/// v1's cpu.cfs_quota_us other than -1.
bool QuotaAtOrAbove(std::string dir, const std::string& root, const std::string& file) {
  while (true) {
    const std::string q = FirstWord(dir + "/" + file);
    if (!q.empty() && q != "max" && q != "-1") return true;
    if (dir.size() <= root.size()) return false;
    dir = dir.substr(0, dir.rfind('/'));
  }
}

}  // namespace

std::string CpuidleDriver() { return FirstWord("/sys/devices/system/cpu/cpuidle/current_driver"); }

std::string CpuidleState0() {
  return FirstWord("/sys/devices/system/cpu/cpu0/cpuidle/state0/name");
}

bool LatencyRequestPolls(const std::string& cpuidle_driver, const std::string& state0) {
  if (cpuidle_driver.empty() || cpuidle_driver == "none") return false;
  // The request makes the governor choose state 0, which polls on x86 (POLL) but halts
  // elsewhere (arm64's WFI); a driver whose state does not say is taken at its word.
  return state0.empty() || state0 == "POLL";
}

std::string CpuQuota() {
  std::ifstream in("/proc/self/cgroup");
  std::string line;
  while (std::getline(in, line)) {
    // "ID:CONTROLLERS:PATH": "0::PATH" under cgroup v2, "N:cpu,cpuacct:PATH" under v1.
    const std::size_t a = line.find(':'), b = line.find(':', a + 1);
    if (a == std::string::npos || b == std::string::npos) continue;
    const std::string controllers = line.substr(a + 1, b - a - 1);
    const std::string path = line.substr(b + 1);
    std::string root, file;
    if (controllers.empty()) {
      root = "/sys/fs/cgroup";
      file = "cpu.max";
    } else {
      std::stringstream list(controllers);
      std::string c;
      bool cpu = false;
      while (std::getline(list, c, ',')) cpu = cpu || c == "cpu";
      if (!cpu) continue;
      root = "/sys/fs/cgroup/" + controllers;
      file = "cpu.cfs_quota_us";
    }
    const std::string dir = path == "/" ? root : root + path;
    if (QuotaAtOrAbove(dir, root, file)) return dir + "/" + file;
  }
  return "";
}

int IdlePoller::Start() {
  if (!threads_.empty()) return spinning();
  stop_ = false;
  // The threads take no signal: shoal run's handlers belong to its main thread.
  sigset_t all, before;
  sigfillset(&all);
  pthread_sigmask(SIG_SETMASK, &all, &before);
  for (int cpu : AllowedCpus()) {
    try {
      threads_.emplace_back(&IdlePoller::Spin, this, cpu);
    } catch (const std::system_error&) {
      break;  // fewer threads than CPUs: those started still keep their CPUs polling
    }
  }
  pthread_sigmask(SIG_SETMASK, &before, nullptr);
  // Each thread says whether it spins before it does; wait for all of them to have said.
  while (said_.load() < static_cast<int>(threads_.size())) std::this_thread::yield();
  return spinning();
}

void IdlePoller::Spin(int cpu) {
  pthread_setname_np(pthread_self(), kIdlePollerThreadName);
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  sched_param p{};
  const bool placed = pthread_setaffinity_np(pthread_self(), sizeof(set), &set) == 0 &&
                      pthread_setschedparam(pthread_self(), SCHED_IDLE, &p) == 0;
  if (placed) ++spinning_;
  ++said_;
  if (!placed) return;
  // No pause instruction in the loop: a hypervisor may take a vCPU that spins on pause for
  // one waiting on a lock and deschedule it, which is the halt this thread is here to avoid.
  while (!stop_.load(std::memory_order_relaxed)) {
  }
  timespec ts{};
  if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts) == 0) {
    cpu_ns_ += static_cast<long long>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
  }
}

double IdlePoller::Stop() {
  stop_ = true;
  for (std::thread& t : threads_) {
    if (t.joinable()) t.join();
  }
  threads_.clear();
  spinning_ = 0;
  said_ = 0;
  return cpu_ns_.exchange(0) * 1e-9;
}

}  // namespace shoal

#include "launcher/idle_poller.h"

#include <pthread.h>
#include <sched.h>
#include <time.h>

#include <fstream>
#include <system_error>

#include "launcher/machine_witness.h"

namespace shoal {

std::string CpuidleDriver() {
  std::ifstream in("/sys/devices/system/cpu/cpuidle/current_driver");
  std::string driver;
  if (!(in >> driver)) return "";
  return driver;
}

bool LatencyRequestPolls(const std::string& cpuidle_driver) {
  return !cpuidle_driver.empty() && cpuidle_driver != "none";
}

int IdlePoller::Start() {
  if (!threads_.empty()) return spinning();
  stop_ = false;
  for (int cpu : AllowedCpus()) {
    try {
      threads_.emplace_back(&IdlePoller::Spin, this, cpu);
    } catch (const std::system_error&) {
      break;  // fewer threads than CPUs: those started still keep their CPUs polling
    }
  }
  // Each thread says whether it spins before it does; wait for all of them to have said.
  int said = 0;
  while (said < static_cast<int>(threads_.size())) {
    said = said_.load();
    if (said < static_cast<int>(threads_.size())) std::this_thread::yield();
  }
  return spinning();
}

void IdlePoller::Spin(int cpu) {
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

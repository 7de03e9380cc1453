// Keeping idle CPUs from halting while a run goes. shoal run's 0 us CPU latency request
// (runtime/process.h) makes the kernel's idle loop poll, but only through a cpuidle driver.
// Without one (many virtual machines: /sys/devices/system/cpu/cpuidle/current_driver says
// "none") an idle CPU halts whatever is asked, and a halted virtual CPU runs again when the
// hypervisor gets to it: on a 2-vCPU VM that made wake-ups 2-50 ms late many times a minute
// (docs/benchmarks.md, "Idle CPUs kept polling"). There the poller does what the request
// cannot: one thread per CPU, pinned to it at SCHED_IDLE, spins, so no CPU is ever idle.
// Any other thread that wakes on that CPU takes it at once (the scheduler preempts a
// SCHED_IDLE thread at every wake-up of a normal or real-time one), so the poller costs
// the run's processes a context switch where they had a wake-up from idle.
#pragma once

#include <atomic>
#include <string>
#include <thread>
#include <vector>

namespace shoal {

/// The kernel's cpuidle driver (e.g. "intel_idle", "acpi_idle", "haltpoll"); "none" when
/// it has none, "" when the kernel does not say (built without cpuidle).
std::string CpuidleDriver();
/// Whether a CPU latency request makes this machine's idle CPUs poll: only a cpuidle driver
/// chooses a polling state for it; without one the idle loop halts.
bool LatencyRequestPolls(const std::string& cpuidle_driver);

class IdlePoller {
 public:
  IdlePoller() = default;
  ~IdlePoller() { Stop(); }
  IdlePoller(const IdlePoller&) = delete;
  IdlePoller& operator=(const IdlePoller&) = delete;
  /// Starts a spinning thread on each CPU this process may use (AllowedCpus). A thread
  /// that cannot be pinned to its CPU or put at SCHED_IDLE ends at once: spinning at normal
  /// priority would take CPU time from the run. Returns how many spin.
  int Start();
  /// Ends the threads; returns the CPU time they took, in seconds.
  double Stop();
  int spinning() const { return spinning_.load(); }

 private:
  void Spin(int cpu);
  std::atomic<bool> stop_{false};
  std::atomic<int> spinning_{0};
  std::atomic<int> said_{0};  // threads that have said whether they spin
  std::atomic<long long> cpu_ns_{0};
  std::vector<std::thread> threads_;
};

}  // namespace shoal

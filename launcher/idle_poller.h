// Keeping idle CPUs from halting while a run goes. shoal run's 0 us CPU latency request
// (runtime/process.h) makes the kernel's idle loop poll, but only through a cpuidle driver.
// Without one (many virtual machines: /sys/devices/system/cpu/cpuidle/current_driver says
// "none") an idle CPU halts whatever is asked, and a halted virtual CPU runs again when the
// hypervisor gets to it: on a 2-vCPU VM that made wake-ups 2-50 ms late many times a minute
// (docs/benchmarks.md, "Idle CPUs kept polling"). There the poller does what the request
// cannot: one thread per CPU, pinned to it at SCHED_IDLE, spins, so no CPU is ever idle.
// A thread of the run that wakes on that CPU takes it at once (the scheduler preempts a
// SCHED_IDLE thread at every wake-up of another thread of its group), so the poller costs
// the run's processes a context switch where they had a wake-up from idle. SCHED_IDLE
// ranks a thread only within its scheduling group (its autogroup, one per setsid(), or its
// cgroup): the processes shoal run starts share its group, but those of another login or
// terminal share the CPUs with the poller as with a busy process. And under a CPU quota the spinning
// would spend the quota and have the whole group held: CpuQuota() says when not to start.
#pragma once

#include <atomic>
#include <string>
#include <thread>
#include <vector>

namespace shoal {

/// The kernel's cpuidle driver (e.g. "intel_idle", "acpi_idle", "haltpoll"); "none" when
/// it has none, "" when the kernel does not say (built without cpuidle).
std::string CpuidleDriver();
/// The name of CPU 0's shallowest idle state ("POLL" on x86), "" when the kernel does not say.
std::string CpuidleState0();
/// Whether a CPU latency request makes this machine's idle CPUs poll: only a cpuidle driver
/// chooses a state for it, and that state (the shallowest) must be one that polls; without a
/// driver the idle loop halts.
bool LatencyRequestPolls(const std::string& cpuidle_driver, const std::string& state0);
/// The cgroup file that limits this process's CPU time (cgroup v2 cpu.max, v1
/// cpu.cfs_quota_us, at its own cgroup or one above), or "" when none does.
std::string CpuQuota();

/// The poller's threads' name (what ps -L and top show).
inline constexpr const char* kIdlePollerThreadName = "shoal idle poll";

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

// What the machine itself did to a real-time run: one thread per CPU, pinned to it at the
// highest SCHED_FIFO priority, wakes at fixed absolute deadlines and records each time it
// woke late (a stall). The run's processes run at normal priority, or at SCHED_FIFO 40-50
// (SHOAL_SCHED_FIFO), and cannot delay such a thread; the machine can (the hypervisor taking
// the virtual CPU away, the kernel with interrupts off). So a stall it saw is the
// machine's; whether it accounts for a process's overrun is the timing verdict's to judge
// (JudgeTiming, launcher/run_report.h; docs/run.md, "When the machine stalls").
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

namespace shoal {

/// Most CPUs shoal run puts a thread of its own on (the witness's, the idle poller's).
inline constexpr int kMaxWatchedCpus = 256;
/// The CPUs this process may run on (its affinity), at most kMaxWatchedCpus; empty if the
/// kernel does not say.
std::vector<int> AllowedCpus();

/// Stalls one thread keeps: a machine that stalls every few seconds fills it in hours; one
/// that stalls more often than that has said what it is long before.
inline constexpr std::size_t kStallRoom = 4096;

/// One stall: from `start_s` (mission time, s) for `length_s`, on CPU `cpu`.
struct MachineStall {
  double start_s = 0.0;
  double length_s = 0.0;
  int cpu = 0;
};

/// Stalls are those of at least this length: shorter lateness is the timers' ordinary
/// jitter on a shared VM (a plain 1 kHz loop's p99 was 2.2-2.3 ms on one, docs/benchmarks.md).
inline constexpr double kMachineStallMinS = 0.002;
/// The witness's period: a stall of length L shows as a wake-up at least L minus this late.
/// At this rate each thread takes about 0.9 % of a CPU on a 2-vCPU VM (docs/run.md).
inline constexpr std::int64_t kWitnessPeriodNs = 2000000;

/// What the witness saw over a run.
struct MachineWatch {
  bool watched = false;      // the threads ran at real-time priority for the whole run
  std::string note;          // why not, when not; else how it watched
  int cpus = 0;              // threads (one per CPU shoal run may use)
  std::int64_t wakeups = 0;  // over all threads
  std::vector<MachineStall> stalls;  // in order of start, every CPU's
  std::int64_t stalls_not_kept = 0;  // beyond each thread's room (kStallRoom)
  double worst_s() const;
  /// The stall that overlaps [from_s, to_s] (mission time) the most, and by how much
  /// (s) in *overlap_s; nullptr if none does. A stall is taken to begin up to one witness
  /// period before its start: the witness notices one only at its next deadline.
  const MachineStall* MostOverlapping(double from_s, double to_s, double* overlap_s) const;
};

/// Folds one thread's wake-ups into stalls. A stall lasts from a deadline the thread could
/// not wake at to when it woke. MachineWitness skips the deadlines a stall passed; a
/// caller that wakes for them too (each at the same instant, less late) gets the same
/// stall.
class StallTracker {
 public:
  explicit StallTracker(int cpu, std::size_t room) : cpu_(cpu) { stalls_.reserve(room); }
  /// The thread was due at `deadline_ns` and woke at `woke_ns` (monotonic, relative to t0).
  void Wake(std::int64_t deadline_ns, std::int64_t woke_ns);
  /// Closes the stall in progress; the stalls, in order.
  std::vector<MachineStall> Finish();
  std::int64_t not_kept() const { return not_kept_; }

 private:
  void Close();
  int cpu_;
  bool open_ = false;
  std::int64_t start_ns_ = 0, end_ns_ = 0;
  std::vector<MachineStall> stalls_;
  std::int64_t not_kept_ = 0;
};

/// Watches from Start to Stop. Without the right to real-time priority or to pin threads
/// (CAP_SYS_NICE, RLIMIT_RTPRIO) it does not watch: a thread at normal priority would
/// count the run's own load as the machine's.
///
/// Why it must not watch here, or "" when it can: run processes at SCHED_FIFO
/// (`fifo_asked`: shoal run --sched-fifo; or SHOAL_SCHED_FIFO in the environment they
/// inherit) under the kernel's real-time
/// throttling (kernel.sched_rt_runtime_us not -1), where a FIFO loop that keeps its CPU
/// busy gets every real-time thread on that CPU held, the witness's with it: its own
/// stall would be counted as the machine's.
std::string WitnessRefusal(bool fifo_asked);
class MachineWitness {
 public:
  MachineWitness() = default;
  ~MachineWitness() { Stop(); }
  MachineWitness(const MachineWitness&) = delete;
  MachineWitness& operator=(const MachineWitness&) = delete;
  /// Starts watching from `t0_ns` (CLOCK_MONOTONIC, the run's tick 0; stalls are given in
  /// seconds from it). A thread that cannot be made leaves the witness not watching.
  void Start(std::int64_t t0_ns);
  /// Stops the threads and returns what they saw.
  MachineWatch Stop();

 private:
  struct Thread {
    int cpu = 0;
    std::thread thread;
    std::vector<MachineStall> stalls;
    std::int64_t wakeups = 0, not_kept = 0;
    std::string refused;  // why it could not watch ("" when it could)
  };
  void Watch(Thread* t);
  std::int64_t t0_ns_ = 0;
  std::atomic<bool> stop_{false};
  std::vector<Thread> threads_;
  bool started_ = false;
};

}  // namespace shoal

// What every Shoal process shares: its command line, signal handling, and dying with
// its parent (so that no process outlives `shoal run`, even after kill -9 of it).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace CLI {
class App;
}

namespace shoal {

enum class Mode { kLockstep, kRealtime };

/// A mode's name on command lines ("lockstep", "realtime"), and back.
inline const char* ModeName(Mode m) { return m == Mode::kRealtime ? "realtime" : "lockstep"; }
inline std::optional<Mode> ParseMode(std::string_view name) {
  if (name == ModeName(Mode::kLockstep)) return Mode::kLockstep;
  if (name == ModeName(Mode::kRealtime)) return Mode::kRealtime;
  return std::nullopt;
}

struct ProcessOptions {
  std::string scenario;
  std::vector<std::string> set;  // --set KEY=VALUE changes of the scenario (shoal run's)
  std::string lcm_url;       // the run's shared bus
  std::string rx_url;        // where this process receives (lockstep clock, SHOAL_RX_<id>); "" = lcm_url
  std::string mode = ModeName(Mode::kLockstep);
  std::int64_t t0_ns = 0;    // realtime: CLOCK_MONOTONIC time of tick 0 (after StartProcess)
  std::int64_t t0_unix_ns = 0;  // --t0-unix-ns: CLOCK_REALTIME time of tick 0, if given
  double duration_s = -1.0;  // < 0: the scenario's
  bool insecure = false;     // no bus authentication (else the key comes from SHOAL_BUS_KEY)
  bool sched_fifo = false;   // --sched-fifo: realtime at SCHED_FIFO, or refuse to start
  Mode parsed_mode() const { return ParseMode(mode).value_or(Mode::kLockstep); }
};

/// Adds the common options to a CLI11 app, and to its --help how a process started alone
/// finds the others of its run (the bus, the key, the start time).
void AddProcessOptions(CLI::App* app, ProcessOptions* opt);

struct Scenario;

/// The start of every process's main(): parses the command line, checks the start time
/// (ResolveStartTime), installs the signal handlers and loads the scenario. Returns -1 to
/// go on, else the exit code (0 after --help, 2 for bad arguments, a bad start time or a
/// bad scenario, reported on stderr as "<name>: ..."). Afterwards opt->t0_ns is tick 0 on
/// this process's CLOCK_MONOTONIC, whichever option gave it.
int StartProcess(CLI::App* app, int argc, char** argv, const std::string& name,
                 ProcessOptions* opt, Scenario* scenario);

/// The start time of a run's tick 0 given as --t0-ns (`monotonic_given`) or --t0-unix-ns
/// (`unix_given`), converted once to CLOCK_MONOTONIC into opt->t0_ns: the process runs on
/// the monotonic clock from then on, so that a step or slew of the wall clock during the
/// run does not move its ticks. Real time needs one of them; both at once, a time more
/// than kMaxStartOffsetNs ahead, or one before the clock can have read (before boot; on
/// the wall clock before kEarliestUnixStartNs) are refused as mistakes (ms for ns, a
/// monotonic time taken for a wall-clock one or the other way round). A time in the past
/// is allowed, however far: a restarted process resumes with the run's original t0.
/// Lockstep reads no clock: only "both at once" is refused there. False with *error.
bool ResolveStartTime(bool monotonic_given, bool unix_given, ProcessOptions* opt,
                      std::string* error);
/// How far ahead of now a start time may be.
constexpr std::int64_t kMaxStartOffsetNs = 86400LL * 1000000000LL;
/// The earliest wall-clock start time taken: 2000-01-01T00:00:00Z (a CLOCK_MONOTONIC value
/// given as --t0-unix-ns reads as a time in 1970).
constexpr std::int64_t kEarliestUnixStartNs = 946684800LL * 1000000000LL;

/// CLOCK_REALTIME now, in nanoseconds since 1970.
std::int64_t RealtimeNs();
/// The CLOCK_MONOTONIC time at which CLOCK_REALTIME reads `unix_ns`, as the two clocks
/// stand now: both are read back to back a few times, and the pair read closest together
/// (least likely to have been preempted between the reads) gives the offset.
std::int64_t MonotonicFromUnixNs(std::int64_t unix_ns);

/// Installs SIGINT/SIGTERM handlers that set StopRequested(), and asks the kernel to send
/// SIGTERM when the parent dies.
void InstallProcessSignals();
bool StopRequested();

/// Real-time mode: timer slack 1 ns and, when permitted (root), SCHED_FIFO at `priority`.
/// Returns a note describing what was applied (for the process's log).
/// Lockstep is a throughput job: SCHED_BATCH, so that a process woken by a message does
/// not preempt the process that is sending it the rest of a burst (with SCHED_OTHER every
/// datagram of a burst costs two context switches). Call before LCM starts its receive
/// thread, so that the thread inherits the policy. Returns what was set, for the log.
std::string EnableBatchScheduling();
/// Real time: timer slack 1 ns, and SCHED_FIFO at `priority` when `required` (the process's
/// --sched-fifo) or SHOAL_SCHED_FIFO asks for it: "emulator" for the channel emulator alone
/// (`clock_master`), any other value for every real-time process. Returns what was set, for
/// the log. A policy the command line asked for and the kernel refused sets *refused (the
/// process then must not start: its loop would run unlike the run it was asked to be); one
/// only the environment asked for is noted and the process goes on under SCHED_OTHER.
std::string EnableRealtimeScheduling(int priority, bool clock_master, bool required = false,
                                     bool* refused = nullptr);

/// SCHED_FIFO priorities in real time: the channel emulator's releases are the delays the
/// run is about, so it stands above the leader's and the vehicles' loops.
inline constexpr int kEmulatorFifoPriority = 50;
inline constexpr int kNodeFifoPriority = 40;

/// A process's scheduling for its mode, said on stderr as "<name>: <policy>": in real time
/// EnableRealtimeScheduling (`priority`, `clock_master`, required by opt.sched_fifo), in
/// lockstep EnableBatchScheduling. False (said why) when --sched-fifo was refused: the
/// process must exit 2. Call before LCM starts its receive thread, which inherits it.
bool EnterScheduling(const std::string& name, const ProcessOptions& opt, int priority,
                     bool clock_master);

/// Whether this process may put a thread at SCHED_FIFO `priority` (CAP_SYS_NICE, which root
/// has, or RLIMIT_RTPRIO; and a cgroup that grants real-time time): tried on a thread of its
/// own, which ends at once. False with *why.
bool SchedFifoPermitted(int priority, std::string* why);
/// After a real-time loop's last tick: SCHED_OTHER at nice 10, so that what a process does
/// on its way out (its last messages, freeing its locked memory) never delays the loops of
/// the processes still running.
void LeaveRealtimeScheduling();

/// Locks the process's pages in memory (mlockall, current and future) when permitted (root,
/// or RLIMIT_MEMLOCK large enough). A locked process takes no page fault in its loop, and
/// its resident size is what it has allocated from the start: LCM's receive ring and the
/// heap's spare pages are otherwise touched page by page as a backlog first reaches them,
/// which a soak's memory verdict would read as growth. Returns what was done, for the log.
std::string LockMemory();

/// A PM QoS request for 0 us CPU wake-up latency (/dev/cpu_dma_latency), held while the
/// object lives (the kernel drops it when the descriptor closes, also if the process dies).
/// Idle CPUs then poll instead of halting. On a VM a halted vCPU is woken through the
/// hypervisor, and a SIL run is a chain of cross-CPU wake-ups (measured on the 2-vCPU VM:
/// lockstep paper_example2 ≈ 20 % faster; docs/benchmarks.md, lockstep). Needs root;
/// without it held() is false and note() says why. The cost: idle CPUs spin for the run's duration.
class CpuLatencyRequest {
 public:
  CpuLatencyRequest();
  ~CpuLatencyRequest();
  CpuLatencyRequest(const CpuLatencyRequest&) = delete;
  CpuLatencyRequest& operator=(const CpuLatencyRequest&) = delete;
  bool held() const { return fd_ >= 0; }
  const std::string& note() const { return note_; }

 private:
  int fd_ = -1;
  std::string note_;
};

}  // namespace shoal

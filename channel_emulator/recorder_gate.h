// Lockstep back-pressure from the run's recorder (lcm-logger). lcm-logger hands each
// message from LCM's receive thread to its handler thread through LCM's subscription
// queue, which holds 30 messages and drops beyond that; a lockstep run produces messages
// as fast as the CPU allows, so whenever the handler thread waits for the CPU while the
// receive thread runs, states are lost from the log. The clock master therefore waits,
// before it releases the next window, until the recorder has handled what it was sent:
// until every thread of the recorder is asleep. A datagram sent on loopback is queued to
// every receiving socket, and its reader woken (made runnable), before the sender's
// sendmsg returns; so once the clock master has received the window's last state, a
// recorder with a thread still runnable has not yet handled it. Linux only (/proc).
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <vector>

namespace shoal {

class RecorderGate {
 public:
  /// pid <= 0: an open gate (Wait returns at once).
  explicit RecorderGate(pid_t pid);
  ~RecorderGate();
  RecorderGate(const RecorderGate&) = delete;
  RecorderGate& operator=(const RecorderGate&) = delete;

  /// Returns once every thread of the recorder is asleep, or after max_wait_ns (counted
  /// in timeouts()), or at once if the recorder is gone (the gate then stays open).
  void Wait(std::int64_t max_wait_ns);

  bool active() const { return pid_ > 0; }
  /// Returns once the recorder's writer has written every event handed to it (nothing is
  /// pending, which lcm-logger stopped by SIGINT would drop), or after max_wait_ns. False
  /// if not attached or if it timed out.
  bool WaitForWritten(std::int64_t max_wait_ns);
  /// Returns once the recorder's writer has written `target` events, or after
  /// max_wait_ns; counted with WaitFor's waits and timeouts. False if not attached.
  bool WaitForWrittenUpTo(std::uint64_t target, std::int64_t max_wait_ns);
  /// Events handed to the writer, and written (0 before Attach succeeds).
  std::uint64_t queued() const;
  std::uint64_t written() const;

  std::int64_t waits() const { return waits_; }        // calls that had to wait
  std::int64_t timeouts() const { return timeouts_; }  // calls that gave up
  std::int64_t waited_ns() const { return waited_ns_; }

 private:
  /// 1: every thread asleep; 0: some thread runnable (or in uninterruptible wait);
  /// -1: the recorder is gone (or a zombie).
  int Idle();
  /// (Re)opens /proc/<pid>/task/<tid>/stat for every thread. Also done whenever the
  /// process's thread count changes: lcm-logger starts its writer and LCM's receive
  /// thread after it creates the log file, and the gate may be set up in between.
  bool Scan();

  pid_t pid_;
  int process_fd_ = -1;   // /proc/<pid>/stat: state and thread count
  std::vector<int> fds_;  // one per thread
  std::int64_t waits_ = 0, timeouts_ = 0, waited_ns_ = 0;
};

/// The recorder's own count of the messages it has handled, when lcm-logger runs with
/// runtime/lcm_queue_shim.c and SHOAL_LOGGER_PROGRESS=1 (a shared memory object named after
/// its pid). With it the clock master bounds how far the recorder falls behind, by what it
/// has sent the recorder's bus, instead of waiting until the recorder is idle: the recorder
/// then records a window while the vehicles step the next. Exact only when the clock master
/// is the only sender on that bus (a run with an uplink); with other senders the recorder's
/// count runs ahead and the bound is looser, never a wait that cannot end.
class RecorderProgress {
 public:
  /// pid <= 0: never attached.
  explicit RecorderProgress(pid_t pid) : pid_(pid) {}
  ~RecorderProgress();
  RecorderProgress(const RecorderProgress&) = delete;
  RecorderProgress& operator=(const RecorderProgress&) = delete;

  /// Whether the recorder's counter runs. Looks for it until it does (the recorder creates
  /// it at its first subscription); once found, removes its name, so nothing is left
  /// behind, and keeps the mapping.
  bool Attach();
  /// Messages the recorder has handled (0 before Attach succeeds).
  std::uint64_t handled() const;
  /// Returns once the recorder has handled `target` messages, less those taken as lost, or
  /// after max_wait_ns (counted in timeouts()). False if not attached (nothing waited).
  /// A wait that gives up while the recorder did nothing at all -- not one message handled,
  /// its writer idle -- takes what it still lacks as lost on the way (a datagram the
  /// recorder's socket never got: sent before it joined the group, or dropped by the
  /// kernel), so that later waits do not each wait the limit for messages that will never
  /// come; what the log lacks is judged from the log itself.
  bool WaitFor(std::uint64_t target, std::int64_t max_wait_ns);
  /// Messages taken as lost on the way to the recorder, at most what of `sent` it has not
  /// handled: a recorder that handles one after all takes it back from the loss.
  std::uint64_t lost(std::uint64_t sent);

  /// Returns once the recorder's writer has written every event handed to it (nothing is
  /// pending, which lcm-logger stopped by SIGINT would drop), or after max_wait_ns. False
  /// if not attached or if it timed out.
  bool WaitForWritten(std::int64_t max_wait_ns);
  /// Returns once the recorder's writer has written `target` events, or after
  /// max_wait_ns; counted with WaitFor's waits and timeouts. False if not attached.
  bool WaitForWrittenUpTo(std::uint64_t target, std::int64_t max_wait_ns);
  /// Events handed to the writer, and written (0 before Attach succeeds).
  std::uint64_t queued() const;
  std::uint64_t written() const;

  std::int64_t waits() const { return waits_; }
  std::int64_t timeouts() const { return timeouts_; }
  std::int64_t waited_ns() const { return waited_ns_; }

 private:
  pid_t pid_;
  const void* map_ = nullptr;  // ShoalLoggerProgress
  std::int64_t waits_ = 0, timeouts_ = 0, waited_ns_ = 0;
  std::uint64_t lost_ = 0;
};

}  // namespace shoal

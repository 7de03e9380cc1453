// One way for every Shoal program to be asked to stop: SIGINT, SIGTERM (and optionally
// SIGHUP) set a flag that the program's loop polls.
#pragma once

#include <csignal>

namespace shoal {

/// While it lives, SIGINT and SIGTERM (and SIGHUP with `hangup`) only set a process-wide
/// flag, read with Requested(); the destructor restores the handlers found before.
/// The flag is cleared on construction: a new scope starts not stopped.
///
/// The handlers are installed without SA_RESTART, so a signal also interrupts a blocking
/// call (nanosleep, poll, waitpid) that the loop then sees return early. With
/// `wake_on_child`, SIGCHLD gets a handler that does nothing, for the same reason: a
/// child's exit ends the parent's wait at once rather than at its next poll.
///
/// For a whole process (never restored), keep one alive for the life of main(), e.g.
/// `static StopSignals signals;`.
class StopSignals {
 public:
  struct Options {
    bool hangup = false;         // SIGHUP stops too (a closed terminal)
    bool wake_on_child = false;  // SIGCHLD interrupts blocking calls
  };
  StopSignals();
  explicit StopSignals(Options options);
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

  /// True once a stop signal arrived (or Request() was called) since the last
  /// construction.
  static bool Requested();
  /// Sets the flag as a signal would (e.g. when the parent is already gone).
  static void Request();

 private:
  struct Saved {
    int signal = 0;
    struct sigaction old = {};
  };
  void Install(int signal, void (*handler)(int));
  Saved saved_[4];
  int n_saved_ = 0;
};

}  // namespace shoal

#include "runtime/stop_signals.h"

namespace shoal {
namespace {

volatile std::sig_atomic_t g_stop_requested = 0;

extern "C" void StopSignalsOnStop(int) { g_stop_requested = 1; }
extern "C" void StopSignalsOnChild(int) {}

}  // namespace

StopSignals::StopSignals() : StopSignals(Options{}) {}

StopSignals::StopSignals(Options options) {
  g_stop_requested = 0;
  Install(SIGINT, StopSignalsOnStop);
  Install(SIGTERM, StopSignalsOnStop);
  if (options.hangup) Install(SIGHUP, StopSignalsOnStop);
  if (options.wake_on_child) Install(SIGCHLD, StopSignalsOnChild);
}

StopSignals::~StopSignals() {
  for (int i = n_saved_ - 1; i >= 0; --i) sigaction(saved_[i].signal, &saved_[i].old, nullptr);
}

bool StopSignals::Requested() { return g_stop_requested != 0; }

void StopSignals::Request() { g_stop_requested = 1; }

void StopSignals::Install(int signal, void (*handler)(int)) {
  struct sigaction sa = {};
  sa.sa_handler = handler;
  sigemptyset(&sa.sa_mask);
  Saved& s = saved_[n_saved_];
  s.signal = signal;
  if (sigaction(signal, &sa, &s.old) == 0) ++n_saved_;  // restore only what was replaced
}

}  // namespace shoal

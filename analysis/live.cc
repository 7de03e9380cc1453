#include "analysis/live.h"

#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <memory>
#include <optional>

#include "runtime/channels.h"
#include "runtime/lcm_bus.h"
#include "runtime/messages.h"
#include "runtime/stop_signals.h"

namespace shoal {
namespace {

std::int64_t WallMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

/// A run-level end: shoal sim / the launcher (-2) or the channel emulator (-1) says the run
/// is over. Vehicles' own "finished" statuses do not end it.
bool RunEnded(const StatusRecord& st) {
  const std::optional<RunState> s = ParseRunState(st.state);
  return st.vehicle_id < 0 && s &&
         (*s == RunState::kFinished || *s == RunState::kFailed || *s == RunState::kInterrupted);
}

}  // namespace

bool ReadLiveRun(const LiveOptions& opt, const LoadOptions& lo, RunData* run, std::string* error) {
  std::unique_ptr<LcmBus> bus;
  try {
    bus = std::make_unique<LcmBus>(opt.url);
  } catch (const std::exception& e) {
    *error = e.what();
    return false;
  }
  *run = RunData();
  run->source = opt.url.empty() ? "LCM default URL" : opt.url;
  RunDataBuilder b(run, lo);
  run->key_used = opt.key.has_value();
  LogVerifier verifier(opt.key, run);
  bool ended = false;
  std::size_t statuses_seen = 0;
  try {
    bus->Subscribe(channels::kAllPattern, [&](const std::string& ch, const void* d, int n) {
      const auto* bytes = static_cast<const std::uint8_t*>(d);
      const int size = verifier.Check(ch, bytes, n);
      if (size < 0) {
        ++run->events;  // received, but not the run's
        return;
      }
      b.Add(ch, bytes, size, WallMicros());
      for (; statuses_seen < run->statuses.size(); ++statuses_seen) {
        ended = ended || RunEnded(run->statuses[statuses_seen]);
      }
    });
  } catch (const std::exception& e) {
    *error = e.what();
    return false;
  }

  const StopSignals signals;  // Ctrl-C ends the listening, not the analysis
  const bool show = opt.progress && isatty(2);
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  auto last_show = t0;
  Clock::time_point end_at = Clock::time_point::max();
  while (!StopSignals::Requested()) {
    if (bus->Handle(50) < 0) {
      if (StopSignals::Requested() || errno == EINTR) continue;  // Ctrl-C interrupts the wait: not an error
      *error = "LCM receive error on " + run->source + " (" + std::strerror(errno) + ")";
      break;
    }
    const auto now = Clock::now();
    if (ended && end_at == Clock::time_point::max()) {
      end_at = now + std::chrono::milliseconds(500);  // the processes' last messages
    }
    if (now >= end_at) break;
    if (opt.duration_s > 0 && now - t0 >= std::chrono::duration<double>(opt.duration_s)) break;
    if (show && now - last_show > std::chrono::milliseconds(500)) {
      last_show = now;
      Micros t = 0;
      for (const VehicleTrack& v : run->vehicles) {
        if (!v.samples.empty()) t = std::max(t, v.samples.back().utime);
      }
      std::fprintf(stderr, "\r  listening on %s: %lld messages, t = %.1f s   ",
                   run->source.c_str(), static_cast<long long>(run->events), ToSeconds(t));
    }
  }
  if (show) std::fprintf(stderr, "\r%100s\r", "");
  b.Finish();
  NoteAuthentication(run);
  if (!error->empty()) return false;
  const bool any = run->state_messages() > 0 || !run->channel_events.empty() ||
                   !run->health.empty() || !run->statuses.empty() || !run->clock.empty();
  if (!any && run->unauthenticated > 0) {
    *error = std::to_string(run->unauthenticated) + " Shoal messages received on " +
             run->source + ", none of them authenticated with the key given (another run's?)";
    return false;
  }
  if (!any) {
    *error = "nothing from a Shoal run received on " + run->source +
             " (is shoal run, shoal sim's log in lcm-logplayer, or a swarm publishing there? "
             "for udpm on one host, multicast must be routed to lo)";
    return false;
  }
  return true;
}


}  // namespace shoal

#include "analysis/live.h"

#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <optional>
#include <utility>

#include "runtime/channels.h"
#include "runtime/lcm_bus.h"
#include "runtime/messages.h"
#include "runtime/stop_signals.h"

// runtime/lcm_recv_guard.h's count, weak: only the shoal program links the guard.
extern "C" unsigned long shoal_lcm_datagrams_refused(void) __attribute__((weak));

namespace shoal {
namespace {

std::int64_t WallMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

constexpr int kRecvBufBytes = 16 << 20;

/// A run-level end: shoal sim / the launcher (-2) or the channel emulator (-1) says the run
/// is over. Vehicles' own "finished" statuses do not end it.
bool RunEnded(const StatusRecord& st) {
  const std::optional<RunState> s = ParseRunState(st.state);
  return st.vehicle_id < 0 && s &&
         (*s == RunState::kFinished || *s == RunState::kFailed || *s == RunState::kInterrupted);
}

/// The sequence numbers of every publisher on the non-state Shoal channels: a forward
/// jump of k + 1 is k messages that did not arrive. A step back (a restarted process
/// counts from 0 again) or a repeat starts the count anew.
class SeqGaps {
 public:
  explicit SeqGaps(LiveStream* out) : out_(out) {}
  void Add(const std::string& ch, const std::uint8_t* d, int n) {
    const channels::Kind k = channels::Parse(ch).kind;
    if (n < 24 || (k != channels::Kind::kChannelEvents && k != channels::Kind::kClock &&
                   k != channels::Kind::kHealth && k != channels::Kind::kStatus)) {
      return;
    }
    // After the 8-byte fingerprint: int64 utime, int32 vehicle_id, int32 seq (big-endian).
    const std::int32_t id = BigEndian32(d + 16), seq = BigEndian32(d + 20);
    auto [it, fresh] = last_.try_emplace({ch, id}, seq);
    if (!fresh && seq > it->second) {
      const std::int64_t gap = static_cast<std::int64_t>(seq) - it->second - 1;
      if (gap > 0) out_->missed_by_channel[ch] += gap;
    }
    it->second = seq;
  }

 private:
  static std::int32_t BigEndian32(const std::uint8_t* p) {
    return static_cast<std::int32_t>((std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) |
                                     (std::uint32_t{p[2]} << 8) | std::uint32_t{p[3]});
  }
  LiveStream* out_;
  std::map<std::pair<std::string, std::int32_t>, std::int32_t> last_;
};

/// The listening: until a signal, the end status (and 500 ms for the last messages), the
/// duration, or the idle limit. Sets run->stream.stopped_by; false on a receive error.
bool Listen(const LiveOptions& opt, LcmBus* bus, const bool* ended, const bool* any,
            const std::chrono::steady_clock::time_point* last_msg, RunData* run,
            std::string* error) {
  using Clock = std::chrono::steady_clock;
  const bool show = opt.progress && isatty(2);
  const auto t0 = Clock::now();
  auto last_show = t0;
  Clock::time_point end_at = Clock::time_point::max();
  std::string& why = run->stream.stopped_by;
  while (why.empty()) {
    if (bus->Handle(50) < 0 && !StopSignals::Requested() && errno != EINTR) {
      *error = "LCM receive error on " + run->source + " (" + std::strerror(errno) + ")";
      why = "error";
      break;
    }
    const auto now = Clock::now();
    if (*ended && end_at == Clock::time_point::max()) {
      end_at = now + std::chrono::milliseconds(500);  // the processes' last messages
    }
    if (StopSignals::Requested()) why = "signal";  // Ctrl-C ends the listening, not the analysis
    else if (now >= end_at) why = "end status";
    else if (opt.duration_s > 0 && now - t0 >= std::chrono::duration<double>(opt.duration_s)) why = "duration";
    else if (opt.until_idle_s > 0 && *any &&
             now - *last_msg >= std::chrono::duration<double>(opt.until_idle_s)) why = "idle";
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
  return error->empty();
}

/// The URL to listen on: a udpm URL without its own recv_buf_size asks for kRecvBufBytes.
/// The kernel's default (about 200 kB, some 90 datagrams) holds three ticks of Example 2;
/// an analysis descheduled longer on a loaded host loses the rest, silently. The kernel
/// caps the request at net.core.rmem_max.
std::string ListenUrl(const std::string& url) {
  if (url.rfind("udpm://", 0) != 0 || url.find("recv_buf_size=") != std::string::npos) return url;
  return url + (url.find('?') == std::string::npos ? "?" : "&") +
         "recv_buf_size=" + std::to_string(kRecvBufBytes);
}

/// The datagrams the guard before LCM's receive thread refused, said as a warning: nothing
/// of a run's is lost that way, but someone on the host sent what LCM would have crashed
/// on.
void NoteRefusedDatagrams(RunData* run) {
  const unsigned long n = shoal_lcm_datagrams_refused ? shoal_lcm_datagrams_refused() : 0;
  if (n == 0) return;
  run->warnings.push_back(std::to_string(n) +
                          " malformed LCM datagram(s) received and refused (not a run's: "
                          "a header that does not add up)");
}

}  // namespace

bool ReadLiveRun(const LiveOptions& opt, const LoadOptions& lo, RunData* run, std::string* error) {
  std::unique_ptr<LcmBus> bus;
  try {
    // LCM's receive thread: its queue in memory absorbs a replay faster than the
    // analysis, where the socket alone would overflow.
    bus = std::make_unique<LcmBus>(ListenUrl(opt.url), std::nullopt,
                                   LcmBus::Receiving::kLcmThread);
  } catch (const std::exception& e) {
    *error = e.what();
    return false;
  }
  *run = RunData();
  run->source = opt.url.empty() ? "LCM default URL" : opt.url;
  run->stream.live = true;
  run->stream.idle_s = opt.until_idle_s > 0 ? opt.until_idle_s : 0.0;
  RunDataBuilder b(run, lo);
  run->key_used = opt.key.has_value();
  LogVerifier verifier(opt.key, run);
  SeqGaps gaps(&run->stream);
  bool ended = false, any = false;
  auto last_msg = std::chrono::steady_clock::now();
  std::size_t statuses_seen = 0;
  try {
    bus->Subscribe(channels::kAllPattern, [&](const std::string& ch, const void* d, int n) {
      any = true;
      last_msg = std::chrono::steady_clock::now();
      const auto* bytes = static_cast<const std::uint8_t*>(d);
      const int size = verifier.Check(ch, bytes, n);
      if (size < 0) {
        ++run->events;  // received, but not the run's
        return;
      }
      gaps.Add(ch, bytes, size);
      b.Add(ch, bytes, size, WallMicros());
      for (; statuses_seen < run->statuses.size(); ++statuses_seen) {
        ended = ended || RunEnded(run->statuses[statuses_seen]);
      }
    });
  } catch (const std::exception& e) {
    *error = e.what();
    return false;
  }
  const StopSignals signals;
  Listen(opt, bus.get(), &ended, &any, &last_msg, run, error);
  run->stream.end_status = ended;
  b.Finish();
  NoteAuthentication(run);
  NoteIgnored(run);
  NoteRefusedDatagrams(run);
  if (!error->empty()) return false;
  const bool got = run->state_messages() > 0 || !run->channel_events.empty() ||
                   !run->health.empty() || !run->statuses.empty() || !run->clock.empty();
  if (!got && run->unauthenticated > 0) {
    *error = std::to_string(run->unauthenticated) + " Shoal messages received on " +
             run->source + ", none of them authenticated with the key given (another run's?)";
    return false;
  }
  if (!got) {
    *error = "nothing from a Shoal run received on " + run->source +
             " (is shoal run, shoal sim's log in lcm-logplayer, or a swarm publishing there? "
             "for udpm on one host, multicast must be routed to lo)";
    return false;
  }
  return true;
}

LiveCompleteness JudgeLiveStream(const RunData& run, const RunAnalysis& a) {
  LiveCompleteness c;
  const std::int64_t expected = a.states_expected - a.states_missing_in_restarts;
  c.states_missed = std::max<std::int64_t>(0, expected - a.summary.states);
  c.messages_missed = run.stream.messages_missed();
  if (!run.stream.end_status) {
    c.reasons.push_back("no run-level end status arrived (the listening stopped: " +
                        run.stream.stopped_by + "): the run may have gone on");
  }
  if (c.states_missed > 0) {
    c.reasons.push_back(std::to_string(c.states_missed) + " of " + std::to_string(expected) +
                        " vehicle states the run should have published did not arrive");
  }
  if (a.states_expected <= 0) c.reasons.push_back("the run's expected states are unknown");
  if (c.messages_missed > 0) {
    std::string by;
    for (const auto& [ch, n] : run.stream.missed_by_channel) {
      by += (by.empty() ? "" : ", ") + ch + " " + std::to_string(n);
    }
    c.reasons.push_back(std::to_string(c.messages_missed) +
                        " other messages did not arrive (sequence gaps: " + by + ")");
  }
  c.complete = c.reasons.empty();
  return c;
}

}  // namespace shoal

// Translation between core structs and the LCM types (the only place that knows both).
#pragma once

#include <algorithm>
#include <cstddef>
#include <optional>
#include <string_view>

#include <shoal/channel_event_t.hpp>
#include <shoal/channel_events_t.hpp>
#include <shoal/clock_window_t.hpp>
#include <shoal/health2_t.hpp>
#include <shoal/health_t.hpp>
#include <shoal/run_status_t.hpp>
#include <shoal/vehicle_state_t.hpp>

#include "core/channel_model.h"
#include "core/follower.h"
#include "core/state_msg.h"
#include "runtime/clock.h"

namespace shoal {

/// run_status_t.state: what a process (or the run) is doing, as its status says it.
enum class RunState {
  kStarting,     // the launcher is starting the processes
  kReady,        // lockstep: a vehicle waits for the first clock window
  kRunning,
  kFinished,
  kFailed,       // did not start or could not go on
  kInterrupted,  // stopped by a signal
  kVehicleLost,  // lockstep: a vehicle stopped answering (the run goes on without it)
  kRestarted,    // a process restarted in place of one that died (shoal run --restart)
};

inline const char* RunStateName(RunState s) {
  switch (s) {
    case RunState::kStarting: return "starting";
    case RunState::kReady: return "ready";
    case RunState::kRunning: return "running";
    case RunState::kFinished: return "finished";
    case RunState::kFailed: return "failed";
    case RunState::kInterrupted: return "interrupted";
    case RunState::kVehicleLost: return "vehicle_lost";
    case RunState::kRestarted: return "restarted";
  }
  return "";
}

/// The state a run_status_t.state names; nullopt for any other text.
inline std::optional<RunState> ParseRunState(std::string_view name) {
  for (RunState s : {RunState::kStarting, RunState::kReady, RunState::kRunning,
                     RunState::kFinished, RunState::kFailed, RunState::kInterrupted,
                     RunState::kVehicleLost, RunState::kRestarted}) {
    if (name == RunStateName(s)) return s;
  }
  return std::nullopt;
}

inline void Copy5(const Vec5& v, double* out) {
  for (int k = 0; k < 5; ++k) out[k] = v(k);
}
inline Vec5 Load5(const double* in) { return Eigen::Map<const Vec5>(in); }

inline vehicle_state_t ToLcm(const StateMsg& m) {
  vehicle_state_t o;
  o.utime = m.utime;
  o.vehicle_id = m.vehicle_id;
  o.seq = m.seq;
  Copy5(m.eta, o.eta);
  Copy5(m.nu, o.nu);
  Copy5(m.eta_dot, o.eta_dot);
  Copy5(m.accel_cmd, o.accel_cmd);
  Copy5(m.tau, o.tau);
  o.flags = m.flags;
  return o;
}

inline StateMsg FromLcm(const vehicle_state_t& o) {
  StateMsg m;
  m.utime = o.utime;
  m.vehicle_id = o.vehicle_id;
  m.seq = o.seq;
  m.eta = Load5(o.eta);
  m.nu = Load5(o.nu);
  m.eta_dot = Load5(o.eta_dot);
  m.accel_cmd = Load5(o.accel_cmd);
  m.tau = Load5(o.tau);
  m.flags = o.flags;
  return m;
}

inline channel_event_t ToLcm(const ChannelDecision& d, std::int32_t seq) {
  channel_event_t e;
  e.utime = d.send_utime;
  e.vehicle_id = -1;
  e.seq = seq;
  e.sender = d.sender;
  e.receiver = d.receiver;
  e.msg_seq = d.msg_seq;
  e.send_utime = d.send_utime;
  e.delay_s = d.delay_s;
  e.deliver_utime = d.deliver_utime;
  e.status = d.status;
  e.reason = DropReason(d.status);
  return e;
}

/// SHOAL_CHANNEL batching: decisions are added one by one (each becomes a channel_event_t
/// with the next event seq) and published together by Flush. One message per lockstep
/// window or shoal sim tick instead of one per decision: lcm-logger pays a few thread
/// wake-ups per message, and the decisions were most of the messages it had to log.
class ChannelEventBatch {
 public:
  // At most 76 bytes an event (a drop's reason included): 800 stay under LCM's 65,499
  // bytes for a message sent in one datagram.
  static constexpr int kMaxEvents = 800;

  void Add(const ChannelDecision& d) {
    b_.events.push_back(ToLcm(d, static_cast<std::int32_t>(event_seq_++)));
  }
  bool empty() const { return b_.events.empty(); }
  std::size_t size() const { return b_.events.size(); }

  /// Hands the collected events to publish(const channel_events_t&), at most kMaxEvents per
  /// message, in decision order, and starts a new batch.
  template <typename F>
  void Flush(F&& publish) {
    // Stamps a message: its seq, its count, and the newest decision it holds as its time.
    const auto stamp = [this](channel_events_t* m) {
      m->vehicle_id = -1;
      m->seq = static_cast<std::int32_t>(batch_seq_++);
      m->n_events = static_cast<std::int32_t>(m->events.size());
      m->utime = 0;
      for (const channel_event_t& e : m->events) m->utime = std::max(m->utime, e.utime);
    };
    if (b_.events.size() <= static_cast<std::size_t>(kMaxEvents)) {
      if (b_.events.empty()) return;
      stamp(&b_);
      publish(static_cast<const channel_events_t&>(b_));
    } else {
      channel_events_t part;
      for (std::size_t i = 0; i < b_.events.size(); i += kMaxEvents) {
        const std::size_t end = std::min(b_.events.size(), i + kMaxEvents);
        part.events.assign(b_.events.begin() + static_cast<std::ptrdiff_t>(i),
                           b_.events.begin() + static_cast<std::ptrdiff_t>(end));
        stamp(&part);
        publish(static_cast<const channel_events_t&>(part));
      }
    }
    b_.events.clear();
  }

 private:
  channel_events_t b_{};
  // Counted unsigned, so that a run with more than 2^31 decisions (a long run of many
  // links) wraps to negative numbers on the int32 of the wire rather than overflowing;
  // readers use these numbers only to tell a publisher's messages apart.
  std::uint32_t event_seq_ = 0;
  std::uint32_t batch_seq_ = 0;
};

/// Health of a follower; lateness/overrun fields are the caller's (zero in sim/lockstep).
inline health_t ToLcmHealth(Micros utime, const Follower& f, std::int32_t seq) {
  const FollowerCounters& c = f.counters();
  health_t h;
  h.utime = utime;
  h.vehicle_id = f.id();
  h.seq = seq;
  h.ticks = c.ticks;
  h.lateness_p50_s = 0.0;
  h.lateness_p99_s = 0.0;
  h.lateness_max_s = 0.0;
  h.overruns = 0;
  h.msgs_received = c.msgs_received;
  h.msgs_dropped_invalid = c.msgs_dropped_invalid;
  h.msgs_dropped_old = c.msgs_dropped_old;
  h.neighbour_timeouts = c.neighbour_timeouts;
  h.active_neighbours = c.active_neighbours;
  h.saturated_ticks = c.saturated_ticks;
  h.saturation_fraction = c.ticks > 0 ? static_cast<double>(c.saturated_ticks) / c.ticks : 0.0;
  return h;
}

static_assert(health2_t::LATENESS_BINS == LatenessBins::kCount,
              "health2_t.lcm's lateness_window_bins must have LatenessBins's layout");

/// The report published and logged on SHOAL_HEALTH_<id>: the app's health `h` and the
/// lateness samples `w` taken since the previous report (empty in sim and lockstep).
inline health2_t ToLcmHealth2(const health_t& h, const LatenessWindow& w) {
  health2_t r;
  r.utime = h.utime;
  r.vehicle_id = h.vehicle_id;
  r.seq = h.seq;
  r.ticks = h.ticks;
  r.lateness_p50_s = h.lateness_p50_s;
  r.lateness_p99_s = h.lateness_p99_s;
  r.lateness_max_s = h.lateness_max_s;
  r.overruns = h.overruns;
  r.msgs_received = h.msgs_received;
  r.msgs_dropped_invalid = h.msgs_dropped_invalid;
  r.msgs_dropped_old = h.msgs_dropped_old;
  r.neighbour_timeouts = h.neighbour_timeouts;
  r.active_neighbours = h.active_neighbours;
  r.saturated_ticks = h.saturated_ticks;
  r.saturation_fraction = h.saturation_fraction;
  r.lateness_window_count = w.count();
  r.lateness_window_max_s = w.max();
  std::copy(w.bins().begin(), w.bins().end(), r.lateness_window_bins);
  return r;
}

}  // namespace shoal

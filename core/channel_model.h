// Delay tau(t) and loss models of one directed link, and the channel that applies them.
// Used by shoal sim in-process and by the channel-emulator process.
#pragma once

#include <algorithm>
#include <cmath>
#include <map>
#include <queue>
#include <utility>
#include <vector>

#include "core/rng.h"
#include "core/scenario.h"
#include "core/topology.h"

namespace shoal {

/// tau(t) in seconds for a message sent at t (seconds). Draws from `rng` only for the
/// uniform model. Never negative.
inline double DelaySeconds(const DelayConfig& c, double t_s, Rng* rng) {
  double tau = 0.0;
  switch (c.kind) {
    case DelayKind::kNone:
      break;
    case DelayKind::kConstant:
      tau = c.base_s;
      break;
    case DelayKind::kSinusoid:
      tau = c.base_s + c.amplitude_s * std::cos(c.omega_rad_s * t_s);
      break;
    case DelayKind::kUniform:
      tau = c.base_s + c.amplitude_s * (2.0 * rng->Uniform() - 1.0);
      break;
  }
  return std::max(tau, 0.0);
}

/// The deterministic part of tau(t), used where a single delay value is needed without
/// a draw (the delayed arguments of the paper's uncertain factor): uniform -> base_s.
inline double NominalDelaySeconds(const DelayConfig& c, double t_s) {
  if (c.kind == DelayKind::kUniform) return c.base_s;
  return DelaySeconds(c, t_s, nullptr);
}

inline bool SameDelay(const DelayConfig& a, const DelayConfig& b) {
  return a.kind == b.kind && a.base_s == b.base_s && a.amplitude_s == b.amplitude_s &&
         a.omega_rad_s == b.omega_rad_s;
}

/// True if the loss model drops this message.
inline bool Dropped(const LossConfig& c, Rng* rng) {
  if (c.kind == LossKind::kNone) return false;
  return rng->Uniform() < c.probability;
}

/// Upper bound h of tau(t) for a delay model.
inline double MaxDelaySeconds(const DelayConfig& c) {
  switch (c.kind) {
    case DelayKind::kNone:
      return 0.0;
    case DelayKind::kConstant:
      return c.base_s;
    default:
      return c.base_s + c.amplitude_s;
  }
}

/// One channel decision (becomes a channel_event_t).
struct ChannelDecision {
  int sender = 0;
  int receiver = 0;
  std::int32_t msg_seq = 0;
  Micros send_utime = 0;
  double delay_s = 0.0;
  Micros deliver_utime = 0;
  enum Status : std::int8_t { kDelivered = 0, kDroppedLoss = 1, kDroppedQueue = 2 } status =
      kDelivered;
};

/// A directed link with its resolved models and its own random stream.
struct Link {
  int from = 0;
  int to = 0;
  DelayConfig delay;
  LossConfig loss;
  Rng rng;
};

/// Builds the links of the topology with the scenario's defaults and per-link overrides.
/// Each link's random stream depends only on (seed, from, to).
std::vector<Link> BuildLinks(const Scenario& s, const Topology& topo);

/// When a message sent at send_utime with delay tau becomes usable.
///   period_us > 0 (lockstep and shoal sim): at the first tick at or after send + tau, and
///   never before the tick after the send tick (a state published at tick k is usable from
///   tick k+1 at the earliest).
///   period_us == 0 (real time): at send + tau exactly.
inline Micros DeliveryTime(Micros send_utime, double delay_s, Micros period_us) {
  const Micros due = send_utime + static_cast<Micros>(std::llround(delay_s * 1e6));
  if (period_us <= 0) return due;
  const Micros send_tick = send_utime / period_us;
  Micros tick = (due + period_us - 1) / period_us;  // ceil for due >= 0
  tick = std::max(tick, send_tick + 1);
  return tick * period_us;
}

/// The channel: applies each link's delay and loss and keeps pending messages in a
/// time-ordered queue. Payload is whatever the user forwards (a decoded state in
/// shoal sim, the raw bytes in the emulator process).
template <typename Payload>
class Channel {
 public:
  Channel(std::vector<Link> links, Micros period_us, std::size_t max_pending = 1 << 20)
      : links_(std::move(links)), period_us_(period_us), max_pending_(max_pending) {
    for (std::size_t k = 0; k < links_.size(); ++k) by_sender_[links_[k].from].push_back(k);
  }

  /// A message from `sender` sent at `send_utime`: decides for every outgoing link,
  /// appends one decision per link to `decisions` and queues the deliveries.
  void Submit(int sender, std::int32_t seq, Micros send_utime, const Payload& payload,
              std::vector<ChannelDecision>* decisions) {
    auto it = by_sender_.find(sender);
    if (it == by_sender_.end()) return;
    const double t_s = ToSeconds(send_utime);
    // The payload is stored once and shared by its deliveries (reference counted).
    const int slot = Store(payload);
    bool have_last = false;
    DelayConfig last_cfg;
    double last_delay = 0.0;
    for (std::size_t k : it->second) {
      Link& l = links_[k];
      ChannelDecision d;
      d.sender = sender;
      d.receiver = l.to;
      d.msg_seq = seq;
      d.send_utime = send_utime;
      // Both draws happen for every message so that a link's stream does not depend on
      // the other model's outcome.
      const bool lost = Dropped(l.loss, &l.rng);
      // Links usually share one deterministic model: evaluate tau(t) once per message.
      if (l.delay.kind != DelayKind::kUniform && have_last && SameDelay(l.delay, last_cfg)) {
        d.delay_s = last_delay;
      } else {
        d.delay_s = DelaySeconds(l.delay, t_s, &l.rng);
        last_cfg = l.delay;
        last_delay = d.delay_s;
        have_last = l.delay.kind != DelayKind::kUniform;
      }
      if (lost) {
        d.status = ChannelDecision::kDroppedLoss;
      } else if (queue_.size() >= max_pending_) {
        d.status = ChannelDecision::kDroppedQueue;
      } else {
        d.deliver_utime = DeliveryTime(send_utime, d.delay_s, period_us_);
        queue_.push(Pending{d.deliver_utime, order_++, l.to, slot});
        ++refs_[slot];
      }
      decisions->push_back(d);
    }
    if (refs_[slot] == 0) free_.push_back(slot);
  }

  /// Time of the earliest pending delivery, or -1 if none.
  Micros NextDue() const { return queue_.empty() ? -1 : queue_.top().due; }
  std::size_t pending() const { return queue_.size(); }

  /// Delivers, in (due time, submission order), every message due at or before `now`:
  /// fn(receiver, payload).
  template <typename F>
  void DeliverDue(Micros now, F&& fn) {
    while (!queue_.empty() && queue_.top().due <= now) {
      const Pending p = queue_.top();
      queue_.pop();
      fn(p.receiver, static_cast<const Payload&>(pool_[p.slot]));
      if (--refs_[p.slot] == 0) free_.push_back(p.slot);
    }
  }

  const std::vector<Link>& links() const { return links_; }

 private:
  struct Pending {
    Micros due;
    std::uint64_t order;
    int receiver;
    int slot;  // index into pool_
    bool operator>(const Pending& o) const {
      return due != o.due ? due > o.due : order > o.order;
    }
  };

  int Store(const Payload& payload) {
    if (free_.empty()) {
      pool_.push_back(payload);
      refs_.push_back(0);
      return static_cast<int>(pool_.size()) - 1;
    }
    const int slot = free_.back();
    free_.pop_back();
    pool_[slot] = payload;
    return slot;
  }

  std::vector<Payload> pool_;
  std::vector<int> refs_;
  std::vector<int> free_;
  std::vector<Link> links_;
  std::map<int, std::vector<std::size_t>> by_sender_;
  Micros period_us_;
  std::size_t max_pending_;
  std::uint64_t order_ = 0;
  std::priority_queue<Pending, std::vector<Pending>, std::greater<Pending>> queue_;
};

}  // namespace shoal

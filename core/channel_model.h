// Delay tau(t) and loss models of one directed link, and the channel that applies them.
// Used by shoal sim in-process and by the channel-emulator process.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <queue>
#include <utility>
#include <vector>

#include "core/rng.h"
#include "core/scenario.h"
#include "core/timeline.h"
#include "core/topology.h"

namespace shoal {

/// A trace's delay at t: zero-order hold (the row at or before t) or linear interpolation
/// between the rows around t; before the first row the first delay, after the last row
/// the last delay.
inline double TraceDelaySeconds(const DelayTrace& tr, double t_s) {
  const std::vector<double>& t = tr.t_s;
  if (t.empty()) return 0.0;
  if (!(t_s > t.front())) return tr.delay_s.front();
  if (t_s >= t.back()) return tr.delay_s.back();
  const auto k = static_cast<std::size_t>(std::upper_bound(t.begin(), t.end(), t_s) - t.begin());
  // t[k - 1] <= t_s < t[k]
  const double d0 = tr.delay_s[k - 1];
  if (tr.hold) return d0;
  const double f = (t_s - t[k - 1]) / (t[k] - t[k - 1]);
  return d0 + f * (tr.delay_s[k] - d0);
}

/// std::cos(x), remembering the last argument of the calling thread: tau(t) of a
/// sinusoidal delay is asked for at each tick's time by the channel and by the uncertain
/// factor's environment, and cos of a large argument costs a range reduction.
inline double CosOfLast(double x) {
  thread_local double last_x = 0.0, last_cos = 1.0;
  if (x != last_x) {  // a NaN argument is never remembered
    last_cos = std::cos(x);
    last_x = x;
  }
  return last_cos;
}

/// tau(t) in seconds for a message sent at t (seconds) over `range_m` metres (only the
/// acoustic model uses the range). Draws from `rng` only for the uniform model and the
/// acoustic model's jitter (jitter_s > 0). Never negative.
inline double DelaySeconds(const DelayConfig& c, double t_s, Rng* rng, double range_m = 0.0) {
  double tau = 0.0;
  switch (c.kind) {
    case DelayKind::kNone:
      break;
    case DelayKind::kConstant:
      tau = c.base_s;
      break;
    case DelayKind::kSinusoid:
      tau = c.base_s + c.amplitude_s * CosOfLast(c.omega_rad_s * t_s);
      break;
    case DelayKind::kUniform:
      tau = c.base_s + c.amplitude_s * (2.0 * rng->Uniform() - 1.0);
      break;
    case DelayKind::kAcoustic:
      tau = range_m / c.sound_speed_mps + c.processing_s;
      if (c.jitter_s > 0.0) tau += c.jitter_s * rng->Uniform();
      break;
    case DelayKind::kTrace:
      tau = c.trace ? TraceDelaySeconds(*c.trace, t_s) : 0.0;
      break;
  }
  return std::max(tau, 0.0);
}

/// True if tau(t) depends on nothing but the model and t (no draw, no range): such a
/// value can be computed once per (model, t) and shared by links.
inline bool DeterministicDelay(DelayKind k) {
  return k != DelayKind::kUniform && k != DelayKind::kAcoustic;
}

/// The deterministic part of tau(t), used where a single delay value is needed without
/// a draw (the delayed arguments of the paper's uncertain factor): uniform -> base_s,
/// acoustic -> its delay at half its maximum range, without jitter.
inline double NominalDelaySeconds(const DelayConfig& c, double t_s) {
  if (c.kind == DelayKind::kUniform) return c.base_s;
  if (c.kind == DelayKind::kAcoustic) {
    return 0.5 * c.max_range_m / c.sound_speed_mps + c.processing_s;
  }
  return DelaySeconds(c, t_s, nullptr);
}

inline bool SameDelay(const DelayConfig& a, const DelayConfig& b) {
  return a.kind == b.kind && a.base_s == b.base_s && a.amplitude_s == b.amplitude_s &&
         a.omega_rad_s == b.omega_rad_s && a.trace == b.trace &&
         a.sound_speed_mps == b.sound_speed_mps && a.processing_s == b.processing_s &&
         a.jitter_s == b.jitter_s && a.max_range_m == b.max_range_m &&
         a.loss_at_max_range == b.loss_at_max_range;
}

/// True if the loss model drops this message. `bad` is the link's Gilbert-Elliott state
/// (moved first, then the loss drawn in the new state); the other models ignore it.
inline bool Dropped(const LossConfig& c, Rng* rng, bool* bad = nullptr) {
  switch (c.kind) {
    case LossKind::kNone:
      return false;
    case LossKind::kBernoulli:
      return rng->Uniform() < c.probability;
    case LossKind::kGilbertElliott: {
      const double move = rng->Uniform();
      *bad = *bad ? !(move < c.p_bad_to_good) : move < c.p_good_to_bad;
      return rng->Uniform() < (*bad ? c.loss_bad : c.loss_good);
    }
  }
  return false;
}

/// The acoustic model's chance of losing a message over `range_m` within max_range_m:
/// 0 up to half the range, rising linearly to loss_at_max_range at max_range_m.
inline double AcousticRangeLoss(const DelayConfig& c, double range_m) {
  const double half = 0.5 * c.max_range_m;
  if (!(range_m > half) || half <= 0.0) return 0.0;
  return c.loss_at_max_range * std::min(1.0, (range_m - half) / half);
}

/// Upper bound h of tau(t) for a delay model.
inline double MaxDelaySeconds(const DelayConfig& c) {
  switch (c.kind) {
    case DelayKind::kNone:
      return 0.0;
    case DelayKind::kConstant:
      return c.base_s;
    case DelayKind::kAcoustic:
      return c.max_range_m / c.sound_speed_mps + c.processing_s + c.jitter_s;
    case DelayKind::kTrace:
      return c.trace && !c.trace->delay_s.empty()
                 ? *std::max_element(c.trace->delay_s.begin(), c.trace->delay_s.end())
                 : 0.0;
    default:
      return c.base_s + c.amplitude_s;
  }
}

/// Lower bound of tau(t) for a delay model (never negative: DelaySeconds clips at 0).
/// Acoustic: processing_s (the range can be about 0).
inline double MinDelaySeconds(const DelayConfig& c) {
  switch (c.kind) {
    case DelayKind::kNone:
      return 0.0;
    case DelayKind::kConstant:
      return std::max(c.base_s, 0.0);
    case DelayKind::kAcoustic:
      return std::max(c.processing_s, 0.0);
    case DelayKind::kTrace:
      return c.trace && !c.trace->delay_s.empty()
                 ? std::max(0.0, *std::min_element(c.trace->delay_s.begin(),
                                                   c.trace->delay_s.end()))
                 : 0.0;
    default:
      return std::max(c.base_s - std::fabs(c.amplitude_s), 0.0);
  }
}

/// The fewest control ticks between a message's send tick and its delivery tick that a
/// delay of at least `min_delay_s` can give under DeliveryTime's rule (at least 1). One
/// microsecond of slack covers the rounding of tau to whole microseconds.
inline std::int64_t MinDeliveryLagTicks(double min_delay_s, Micros period_us) {
  const auto d = static_cast<Micros>(std::floor(min_delay_s * 1e6)) - 1;
  if (period_us <= 0 || d <= 0) return 1;
  return std::max<std::int64_t>(1, (d + period_us - 1) / period_us);
}

/// One channel decision (becomes a channel_event_t).
struct ChannelDecision {
  int sender = 0;
  int receiver = 0;
  std::int32_t msg_seq = 0;
  Micros send_utime = 0;
  double delay_s = 0.0;
  Micros deliver_utime = 0;
  // Values of channel_event_t.status. 3 (invalid) is the analysis's own; 4 and 5 came
  // with the acoustic models: a new value of the int8 field, not a new layout.
  enum Status : std::int8_t {
    kDelivered = 0,
    kDroppedLoss = 1,
    kDroppedQueue = 2,
    kSkippedBusy = 4,   // the sender's modem was busy: the state was never transmitted
    kDroppedRange = 5,  // acoustic: the receiver was beyond max_range_m
    // Timeline events ([[event]]):
    kSkippedSilent = 6,    // the sender was silent: the state was never transmitted
    kDroppedLinkDown = 7,  // the link was down
    kDroppedDeaf = 8,      // the receiver was deaf when the message was due
  } status = kDelivered;
};

/// True for the statuses of a state that was never transmitted (the sender's modem was
/// busy or silent): not a message sent, so neither delivered nor lost.
inline bool NotTransmitted(std::int8_t status) {
  return status == ChannelDecision::kSkippedBusy || status == ChannelDecision::kSkippedSilent;
}

/// Why a decision dropped its message, as channel_event_t.reason says it ("" delivered).
inline const char* DropReason(ChannelDecision::Status s) {
  switch (s) {
    case ChannelDecision::kDroppedLoss:
      return "loss model";
    case ChannelDecision::kDroppedQueue:
      return "pending queue full";
    case ChannelDecision::kSkippedBusy:
      return "modem busy";
    case ChannelDecision::kDroppedRange:
      return "out of acoustic range";
    case ChannelDecision::kSkippedSilent:
      return "sender silent";
    case ChannelDecision::kDroppedLinkDown:
      return "link down";
    case ChannelDecision::kDroppedDeaf:
      return "receiver deaf";
    case ChannelDecision::kDelivered:
      break;
  }
  return "";
}

/// A directed link with its resolved models and its own random stream.
struct Link {
  int from = 0;
  int to = 0;
  DelayConfig delay;
  LossConfig loss;
  Rng rng;
  Rng loss_rng;        // Gilbert-Elliott only: its own stream
  bool ge_bad = false;  // Gilbert-Elliott state; every link starts good
  int delay_id = -1;    // set by Channel: links with equal delay models share an id
};

/// Builds the links of the topology with the scenario's defaults and per-link overrides.
/// Each link's random streams depend only on (seed, from, to).
std::vector<Link> BuildLinks(const Scenario& s, const Topology& topo);
/// The links of every topology the scenario's timeline produces (UnionTopology): the
/// links a channel serves.
std::vector<Link> BuildAllLinks(const Scenario& s);

/// Each sender's modem interval in whole microseconds, index = vehicle id 0..n (all 0
/// without a rate limit).
std::vector<Micros> ModemIntervals(const Scenario& s);

/// Lookahead of a set of links (period > 0): no message is delivered fewer than this many
/// ticks after its send tick, on any of them (1 without links).
inline std::int64_t MinLagTicks(const std::vector<Link>& links, Micros period_us) {
  std::int64_t lag = std::numeric_limits<std::int64_t>::max();
  for (const Link& l : links) {
    lag = std::min(lag, MinDeliveryLagTicks(MinDelaySeconds(l.delay), period_us));
  }
  return links.empty() ? 1 : lag;
}

/// The largest delay any of the links' models can give.
inline double MaxDelaySeconds(const std::vector<Link>& links) {
  double d = 0.0;
  for (const Link& l : links) d = std::max(d, MaxDelaySeconds(l.delay));
  return d;
}

/// Lookahead of the links with the delay models a timeline's channel events give them.
inline std::int64_t MinLagTicks(const std::vector<Link>& links, const Timeline* timeline,
                                Micros period_us) {
  std::int64_t lag = MinLagTicks(links, period_us);
  if (timeline == nullptr) return lag;
  for (const DelayConfig& d : timeline->EventDelays()) {
    lag = std::min(lag, MinDeliveryLagTicks(MinDelaySeconds(d), period_us));
  }
  return lag;
}

/// The largest delay of the links and of the models a timeline's channel events give.
inline double MaxDelaySeconds(const std::vector<Link>& links, const Timeline* timeline) {
  double d = MaxDelaySeconds(links);
  if (timeline == nullptr) return d;
  for (const DelayConfig& e : timeline->EventDelays()) d = std::max(d, MaxDelaySeconds(e));
  return d;
}

/// When a message sent at send_utime with delay tau becomes usable. Time is whole
/// microseconds: tau is rounded to the nearest microsecond first.
///   period_us > 0 (lockstep and shoal sim): at the first tick at or after send + tau, and
///   never before the tick after the send tick (a state published at tick k is usable from
///   tick k+1 at the earliest).
///   period_us == 0 (real time): at send + tau exactly.
inline Micros DeliveryTime(Micros send_utime, double delay_s, Micros period_us) {
  // The loader bounds every delay far below this; the clamp keeps a larger one from
  // overflowing into the past (never sooner than it says).
  const Micros due = send_utime + static_cast<Micros>(std::llround(std::min(delay_s * 1e6, 1e18)));
  if (period_us <= 0) return due;
  const Micros send_tick = send_utime / period_us;
  Micros tick = (due + period_us - 1) / period_us;  // ceil for due >= 0
  tick = std::max(tick, send_tick + 1);
  return tick * period_us;
}

/// Lookahead that follows the delay in time: for each send tick, the fewest ticks until
/// any message sent at that tick can be delivered (DeliveryTime's rule, period > 0). A
/// delay model that is a function of time alone (constant, sinusoid, trace) is evaluated
/// at the tick exactly as the channel evaluates it; a model with a draw or a range
/// (uniform, acoustic) counts with its smallest delay. The models are those of the links
/// and of the timeline's channel events, whichever is in force: a bound for every link at
/// every time. With Example 2's tau(t) = 0.1 + 0.05 cos(t) the lag runs from 3 to 8 ticks
/// where MinLagTicks gives 3 throughout.
class LagBound {
 public:
  LagBound(const std::vector<Link>& links, const Timeline* timeline, Micros period_us)
      : period_us_(period_us) {
    if (period_us <= 0) {  // real time: no ticks
      fixed_lag_ = 1;
      return;
    }
    std::vector<DelayConfig> models;
    for (const Link& l : links) models.push_back(l.delay);
    if (timeline != nullptr) {
      for (const DelayConfig& d : timeline->EventDelays()) models.push_back(d);
    }
    for (const DelayConfig& m : models) {
      const bool known = std::any_of(timed_.begin(), timed_.end(),
                                     [&](const DelayConfig& t) { return SameDelay(t, m); });
      if (known) continue;
      // A file with thousands of distinct per-link models would cost that many tau(t)
      // per tick: beyond a few, a model counts with its smallest delay.
      if (DeterministicDelay(m.kind) && timed_.size() < kMaxTimedModels) {
        timed_.push_back(m);
      } else {
        fixed_lag_ = std::min(fixed_lag_, MinDeliveryLagTicks(MinDelaySeconds(m), period_us));
      }
    }
  }

  /// The fewest ticks between tick `tick` and the delivery of any message sent at it (at
  /// least 1; kNoLag without links).
  std::int64_t LagAt(std::int64_t tick) const {
    std::int64_t lag = fixed_lag_;
    const Micros send = tick * period_us_;
    for (const DelayConfig& m : timed_) {
      const Micros due = DeliveryTime(send, DelaySeconds(m, ToSeconds(send), nullptr), period_us_);
      lag = std::min(lag, due / period_us_ - tick);
    }
    return lag;
  }

  /// The longest window [first, first + L) with L <= max_ticks that no message sent
  /// within it is delivered in: everything due in it was sent before `first`.
  std::int64_t Window(std::int64_t first, std::int64_t max_ticks) const {
    std::int64_t reach = first + LagAt(first);  // earliest delivery from the window
    std::int64_t len = 1;
    while (len < max_ticks) {
      reach = std::min(reach, first + len + LagAt(first + len));
      if (reach < first + len + 1) break;
      ++len;
    }
    return len;
  }

  static constexpr std::int64_t kNoLag = std::int64_t{1} << 40;

 private:
  static constexpr std::size_t kMaxTimedModels = 16;
  Micros period_us_;
  std::vector<DelayConfig> timed_;
  std::int64_t fixed_lag_ = kNoLag;
};

/// The channel: applies each link's delay and loss and keeps pending messages in a
/// time-ordered queue. Payload is whatever the user forwards (a decoded state in
/// shoal sim, the raw bytes in the emulator process).
/// With a control period (tick-aligned delivery) the queue is a timing wheel: one bucket
/// per due tick, kept in submission order, so a delivery costs O(1) (a binary heap's
/// unpredictable branches were the largest single cost of shoal sim). In real time
/// (period 0) it is a binary heap on (due time, submission order).
template <typename Payload>
class Channel {
 public:
  /// `modem_interval_us[id]`: sender id's modem interval (ModemIntervals); empty: none.
  /// `timeline`: the scenario's events (null or empty: none); `links` must then be the
  /// links of every topology it produces (BuildAllLinks).
  Channel(std::vector<Link> links, Micros period_us, std::size_t max_pending = 1 << 20,
          std::vector<Micros> modem_interval_us = {},
          std::shared_ptr<const Timeline> timeline = nullptr)
      : links_(std::move(links)),
        timeline_(timeline && !timeline->empty() ? std::move(timeline) : nullptr),
        min_lag_ticks_(shoal::MinLagTicks(links_, timeline_.get(), period_us)),
        period_us_(period_us),
        max_pending_(max_pending),
        modem_interval_us_(std::move(modem_interval_us)) {
    const double max_delay_s = MaxDelaySeconds(links_, timeline_.get());
    for (std::size_t k = 0; k < links_.size(); ++k) {
      const int from = links_[k].from;
      if (from >= static_cast<int>(by_sender_.size())) by_sender_.resize(from + 1);
      by_sender_[from].push_back(k);
      uses_positions_ = uses_positions_ || links_[k].delay.kind == DelayKind::kAcoustic;
      ids_ = std::max({ids_, links_[k].from + 1, links_[k].to + 1});
      if (timeline_) timeline_link_.push_back(timeline_->LinkIndex(links_[k].from, links_[k].to));
    }
    if (timeline_) {
      for (const DelayConfig& d : timeline_->EventDelays()) {
        uses_positions_ = uses_positions_ || d.kind == DelayKind::kAcoustic;
      }
    }
    NumberDelayModels();
    modem_interval_us_.resize(static_cast<std::size_t>(ids_), 0);
    last_tx_us_.assign(static_cast<std::size_t>(ids_), -1);
    if (uses_positions_) where_.resize(static_cast<std::size_t>(ids_));
    if (period_us_ > 0) {
      // Pending deliveries span at most max delay + 2 ticks ahead of the delivered tick.
      // Deliveries further ahead than the wheel wait in overflow_ (a delay of years must
      // not size the wheel by it).
      const double horizon =
          std::min(std::ceil(max_delay_s * 1e6 / period_us_) + 2.0, double{kMaxWheel - 1});
      std::size_t w = 8;
      while (static_cast<double>(w) <= horizon) w *= 2;
      wheel_.resize(w);
      // Every link carries at most one message per tick and holds it at most `horizon`
      // ticks, so this many queue entries are ever pending in the wheel: all of them are
      // made (and touched) now, and a long run allocates nothing for its queue, whatever
      // its delays do meanwhile.
      horizon_ticks_ = static_cast<std::size_t>(horizon);
      AddNodes(std::min(links_.size() * (horizon_ticks_ + 1), kMaxReserved));
    }
  }

  /// Makes now, from `prototype`, as many payloads as can be in transit at once when each
  /// sender submits at most one message per tick (period > 0): the copies stored later
  /// reuse them, so that a payload that owns memory (the emulator's bytes) allocates
  /// nothing in steady state. No effect in real time or on what the channel delivers.
  void ReservePayloads(const Payload& prototype) {
    if (period_us_ <= 0) return;
    std::size_t senders = 0;
    for (const auto& s : by_sender_) senders += !s.empty();
    const std::size_t want = std::min(senders * (horizon_ticks_ + 1), kMaxReserved / 16);
    while (pool_.size() < want) {
      pool_.push_back(prototype);
      refs_.push_back(0);
      free_.push_back(static_cast<int>(pool_.size()) - 1);
    }
  }

  /// A message from `sender` sent at `send_utime` from `sender_pos` (NED, m; only the
  /// acoustic model uses positions): decides for every outgoing link, appends one
  /// decision per link to `decisions` and queues the deliveries.
  void Submit(int sender, std::int32_t seq, Micros send_utime, const Payload& payload,
              std::vector<ChannelDecision>* decisions, const Vec3& sender_pos = Vec3::Zero()) {
    // A receiver that sends to nobody still has its position known.
    if (uses_positions_ && sender >= 0 && sender < ids_) Place(sender, send_utime, sender_pos);
    if (sender < 0 || sender >= static_cast<int>(by_sender_.size()) ||
        by_sender_[sender].empty()) {
      return;
    }
    // A sender with no link in the topology in force sends to nobody and nothing is
    // decided: its modem stays free, so that no later state is "busy" after it.
    if (timeline_ && !AnyLinkInForce(sender, send_utime)) return;
    // A silent sender's modem, or a busy one, transmits nothing: one decision per link
    // of the topology in force says so.
    const bool silent = timeline_ && timeline_->Silent(sender, send_utime);
    if (silent || ModemBusy(sender, send_utime)) {
      for (std::size_t k : by_sender_[sender]) {
        if (!LinkInForce(k, send_utime)) continue;
        decisions->push_back(Decision(sender, links_[k].to, seq, send_utime));
        decisions->back().status =
            silent ? ChannelDecision::kSkippedSilent : ChannelDecision::kSkippedBusy;
      }
      return;
    }
    // An empty wheel can start at the send tick: a first message at a large time must not
    // grow the wheel to cover every tick before it.
    if (period_us_ > 0 && pending_ == 0) next_tick_ = std::max(next_tick_, send_utime / period_us_);
    // The payload is stored once and shared by its deliveries (reference counted).
    const int slot = Store(payload);
    for (std::size_t k : by_sender_[sender]) {
      if (!LinkInForce(k, send_utime)) continue;  // not a link of this topology: no decision
      // Decided in place: a decision built on the stack by narrow stores and copied into
      // the vector by wide loads would stall (the CPU cannot forward such stores).
      ChannelDecision& d = decisions->emplace_back();
      Decide(k, seq, send_utime, sender_pos, &d);
      if (d.status == ChannelDecision::kDelivered) {
        Push(d.deliver_utime, order_++, links_[k].to, slot);
        ++refs_[slot];
      }
    }
    if (refs_[slot] == 0) free_.push_back(slot);
  }

  /// The position the acoustic model uses for `receiver` for a message sent at
  /// `send_utime`, false if none is known. With a control period (shoal sim, lockstep):
  /// the receiver's newest state sent strictly before send_utime, so that the states of
  /// one tick may enter in any order; in real time: its newest state.
  bool ReceiverPosition(int receiver, Micros send_utime, Vec3* pos) const {
    if (!uses_positions_ || receiver < 0 || receiver >= ids_) return false;
    const Where& w = where_[static_cast<std::size_t>(receiver)];
    if (w.have_new && (period_us_ <= 0 || w.t_new < send_utime)) {
      *pos = w.p_new;
      return true;
    }
    if (w.have_old) *pos = w.p_old;
    return w.have_old;
  }

  /// Lookahead (period > 0): no message is ever delivered fewer than this many ticks after
  /// its send tick, on any link. Deliveries due in the next lookahead ticks are therefore
  /// already decided; a lockstep clock master may release that many ticks at once.
  std::int64_t MinLagTicks() const { return min_lag_ticks_; }

  /// Time of the earliest pending delivery, or -1 if none.
  Micros NextDue() const {
    if (pending_ == 0) return -1;
    if (period_us_ <= 0) return heap_.top().due;
    const auto size = static_cast<std::int64_t>(wheel_.size());
    for (std::int64_t t = next_tick_; t < next_tick_ + size; ++t) {
      const Bucket& b = wheel_[static_cast<std::size_t>(t) & (wheel_.size() - 1)];
      if (b.head >= 0) return nodes_[static_cast<std::size_t>(b.head)].p.due;
    }
    return overflow_.top().p.due;  // everything pending is beyond the wheel
  }
  std::size_t pending() const { return pending_; }

  /// Delivers, in (due time, submission order), every message due at or before `now`:
  /// fn(receiver, payload).
  template <typename F>
  void DeliverDue(Micros now, F&& fn) {
    if (period_us_ <= 0) {
      while (!heap_.empty() && heap_.top().due <= now) {
        const Pending p = heap_.top();
        heap_.pop();
        Deliver(p, fn);
      }
      return;
    }
    const std::int64_t now_tick = now / period_us_;
    for (; next_tick_ <= now_tick && pending_ > 0; ++next_tick_) {
      Migrate();
      Bucket& b = wheel_[static_cast<std::size_t>(next_tick_) & (wheel_.size() - 1)];
      for (int k = b.head; k >= 0;) {
        Node& n = nodes_[static_cast<std::size_t>(k)];
        const Pending p = n.p;
        const int next = n.next;
        n.next = free_node_;  // back to the free list before fn runs
        free_node_ = k;
        Deliver(p, fn);
        k = next;
      }
      b = Bucket{};
    }
    next_tick_ = std::max(next_tick_, now_tick + 1);
  }

  const std::vector<Link>& links() const { return links_; }
  /// The scenario's events (null without any).
  const Timeline* timeline() const { return timeline_.get(); }

 private:
  // Numbers the links' delay models: equal deterministic models get one id (so that
  // tau(t) is computed once per model and send time), every other link an id of its own.
  // Links are compared with the first few distinct models only: a scenario rarely has
  // more, and a file with thousands of overrides must not cost links x models.
  void NumberDelayModels() {
    constexpr std::size_t kMaxShared = 16;
    std::vector<std::size_t> firsts;  // first link of each shared model
    int next = 0;
    for (Link& l : links_) {
      l.delay_id = -1;
      if (!DeterministicDelay(l.delay.kind)) continue;  // never shared: stays -1
      for (std::size_t f : firsts) {
        if (SameDelay(links_[f].delay, l.delay)) l.delay_id = links_[f].delay_id;
      }
      if (l.delay_id >= 0) continue;
      l.delay_id = next++;
      if (firsts.size() < kMaxShared) firsts.push_back(static_cast<std::size_t>(&l - links_.data()));
    }
  }

  // True if link k belongs to the topology in force at t (always without a timeline).
  bool AnyLinkInForce(int sender, Micros t) const {
    for (std::size_t k : by_sender_[static_cast<std::size_t>(sender)]) {
      if (LinkInForce(k, t)) return true;
    }
    return false;
  }

  bool LinkInForce(std::size_t k, Micros t) const {
    return !timeline_ || (timeline_link_[k] >= 0 &&
                          timeline_->LinkActive(static_cast<std::size_t>(timeline_link_[k]), t));
  }

  // The decision for one transmitted message on link k: the loss and delay models (a
  // timeline's channel event may replace them), then the timeline's link outage, the
  // pending queue's bound and the receiver's deafness at the due time.
  void Decide(std::size_t k, std::int32_t seq, Micros send_utime, const Vec3& sender_pos,
              ChannelDecision* out) {
    Link& l = links_[k];
    ChannelDecision& d = *out;
    SetDecision(l.from, l.to, seq, send_utime, &d);
    const ScenarioEvent* change =
        timeline_ && timeline_link_[k] >= 0
            ? timeline_->ChannelChange(static_cast<std::size_t>(timeline_link_[k]), send_utime)
            : nullptr;
    const LossConfig& loss = change && change->loss ? *change->loss : l.loss;
    const DelayConfig& delay = change && change->delay ? *change->delay : l.delay;
    // Every draw happens for every message so that a link's stream does not depend on
    // the other model's outcome.
    const bool lost = Dropped(loss, loss.kind == LossKind::kGilbertElliott ? &l.loss_rng : &l.rng,
                              &l.ge_bad);
    if (delay.kind == DelayKind::kAcoustic) {
      d.status = Acoustic(&l, delay, send_utime, sender_pos, &d.delay_s);
    } else if (&delay == &l.delay && l.delay_id >= 0 && l.delay_id == last_id_ &&
               last_t_ == send_utime) {
      // Links usually share one deterministic model and senders one send time: evaluate
      // tau(t) once per (model, t), not once per message and link.
      d.delay_s = last_delay_;
    } else {
      d.delay_s = DelaySeconds(delay, ToSeconds(send_utime), &l.rng);
      last_delay_ = d.delay_s;
      last_t_ = send_utime;
      last_id_ = &delay == &l.delay && DeterministicDelay(delay.kind) ? l.delay_id : -1;
    }
    if (timeline_ && timeline_->LinkDown(static_cast<std::size_t>(timeline_link_[k]), send_utime)) {
      d.status = ChannelDecision::kDroppedLinkDown;
    } else if (lost && d.status == ChannelDecision::kDelivered) {
      d.status = ChannelDecision::kDroppedLoss;
    } else if (d.status == ChannelDecision::kDelivered && pending_ >= max_pending_) {
      d.status = ChannelDecision::kDroppedQueue;
    }
    if (d.status == ChannelDecision::kDelivered) {
      // The links of one send usually share tau: DeliveryTime's divisions once for them.
      if (send_utime != due_send_ || d.delay_s != due_delay_ || !due_valid_) {
        due_ = DeliveryTime(send_utime, d.delay_s, period_us_);
        due_send_ = send_utime;
        due_delay_ = d.delay_s;
        due_valid_ = true;
      }
      d.deliver_utime = due_;
      if (timeline_ && timeline_->Deaf(l.to, d.deliver_utime)) {
        d.status = ChannelDecision::kDroppedDeaf;
        d.deliver_utime = 0;
      }
    }
  }

  // A vehicle's two newest positions (the newest may be of the tick being submitted).
  struct Where {
    Vec3 p_new = Vec3::Zero(), p_old = Vec3::Zero();
    Micros t_new = 0;
    bool have_new = false, have_old = false;
  };

  static ChannelDecision Decision(int sender, int receiver, std::int32_t seq, Micros send_utime) {
    ChannelDecision d;
    SetDecision(sender, receiver, seq, send_utime, &d);
    return d;
  }
  // The message's fields of a decision constructed just before (the others at their
  // defaults: delivered, no delay yet).
  static void SetDecision(int sender, int receiver, std::int32_t seq, Micros send_utime,
                          ChannelDecision* d) {
    d->sender = sender;
    d->receiver = receiver;
    d->msg_seq = seq;
    d->send_utime = send_utime;
  }

  void Place(int id, Micros t, const Vec3& p) {
    Where& w = where_[static_cast<std::size_t>(id)];
    if (w.have_new && w.t_new < t) {
      w.p_old = w.p_new;
      w.have_old = true;
    }
    w.p_new = p;
    w.t_new = t;
    w.have_new = true;
  }

  // True if the sender's modem is still busy with its previous transmission; else the
  // message is transmitted now.
  bool ModemBusy(int sender, Micros send_utime) {
    const Micros interval = modem_interval_us_[static_cast<std::size_t>(sender)];
    if (interval <= 0) return false;
    Micros& last = last_tx_us_[static_cast<std::size_t>(sender)];
    if (last >= 0 && send_utime - last < interval) return true;
    last = send_utime;
    return false;
  }

  // The acoustic model on link l: delay over the sender-receiver range, then the range
  // losses. An unknown receiver position (before its first state) counts as range 0.
  ChannelDecision::Status Acoustic(Link* l, const DelayConfig& model, Micros send_utime,
                                   const Vec3& sender_pos, double* delay) {
    Vec3 rx = sender_pos;
    ReceiverPosition(l->to, send_utime, &rx);
    const double range = (rx - sender_pos).norm();
    *delay = DelaySeconds(model, ToSeconds(send_utime), &l->rng, range);
    const bool draw = model.loss_at_max_range > 0.0;
    const double u = draw ? l->rng.Uniform() : 1.0;
    if (range > model.max_range_m) return ChannelDecision::kDroppedRange;
    return u < AcousticRangeLoss(model, range) ? ChannelDecision::kDroppedLoss
                                                : ChannelDecision::kDelivered;
  }

  struct Pending {
    Micros due;
    std::uint64_t order;
    int receiver;
    int slot;  // index into pool_
    bool operator>(const Pending& o) const {
      return due != o.due ? due > o.due : order > o.order;
    }
  };

  template <typename F>
  void Deliver(const Pending& p, F& fn) {
    --pending_;
    fn(p.receiver, static_cast<const Payload&>(pool_[p.slot]));
    if (--refs_[p.slot] == 0) free_.push_back(p.slot);
  }

  // The fields rather than a Pending: an entry built on the stack by narrow stores and
  // copied into the queue by 16-byte loads stalls the CPU, which cannot forward those
  // stores to the loads; written field by field it goes from registers.
  void Push(Micros due, std::uint64_t order, int receiver, int slot) {
    ++pending_;
    if (period_us_ <= 0) {
      heap_.push(Pending{due, order, receiver, slot});
      return;
    }
    if (due != push_due_ || !push_valid_) {  // deliveries of one send share their due time
      push_tick_ = due / period_us_;
      push_due_ = due;
      push_valid_ = true;
    }
    std::int64_t tick = push_tick_;
    // A message already due (submitted after its delivery tick was delivered) goes out at
    // the next DeliverDue().
    tick = std::max(tick, next_tick_);
    Migrate();
    if (tick - next_tick_ >= static_cast<std::int64_t>(wheel_.size())) {
      overflow_.push(Far{tick, Pending{due, order, receiver, slot}});
      return;
    }
    Append(tick, due, order, receiver, slot);
  }

  // Appends an entry to the bucket of `tick` (within the wheel), taking a free queue entry.
  void Append(std::int64_t tick, Micros due, std::uint64_t order, int receiver, int slot) {
    if (free_node_ < 0) AddNodes(std::max<std::size_t>(nodes_.size(), 8));
    const int k = free_node_;
    Node& n = nodes_[static_cast<std::size_t>(k)];
    free_node_ = n.next;
    n.p.due = due;
    n.p.order = order;
    n.p.receiver = receiver;
    n.p.slot = slot;
    n.next = -1;
    Bucket& b = wheel_[static_cast<std::size_t>(tick) & (wheel_.size() - 1)];
    if (b.tail >= 0) {
      nodes_[static_cast<std::size_t>(b.tail)].next = k;
    } else {
      b.head = k;
    }
    b.tail = k;
  }

  // Adds `count` queue entries to the free list.
  void AddNodes(std::size_t count) {
    const std::size_t first = nodes_.size();
    nodes_.resize(first + count);
    for (std::size_t k = nodes_.size(); k-- > first;) {
      nodes_[k].next = free_node_;
      free_node_ = static_cast<int>(k);
    }
  }

  // Moves the overflowing deliveries whose tick came within the wheel into their buckets,
  // in submission order. Called before any bucket of such a tick is filled or delivered,
  // so each bucket stays in submission order.
  void Migrate() {
    const auto end = next_tick_ + static_cast<std::int64_t>(wheel_.size());
    while (!overflow_.empty() && overflow_.top().tick < end) {
      const Far& f = overflow_.top();
      const std::int64_t tick = std::max(f.tick, next_tick_);  // overdue: the next delivery
      const Pending p = f.p;
      overflow_.pop();
      Append(tick, p.due, p.order, p.receiver, p.slot);
    }
  }

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
  std::shared_ptr<const Timeline> timeline_;  // null: no events
  std::vector<int> timeline_link_;            // per link: its index in the timeline
  std::int64_t min_lag_ticks_;
  std::vector<std::vector<std::size_t>> by_sender_;  // sender id -> its links
  Micros period_us_;
  std::size_t max_pending_;
  std::vector<Micros> modem_interval_us_;  // per sender id
  std::vector<Micros> last_tx_us_;         // per sender id, -1: never transmitted
  bool uses_positions_ = false;            // some link is acoustic
  int ids_ = 0;                            // vehicle ids 0..ids_-1
  std::vector<Where> where_;
  std::uint64_t order_ = 0;
  std::size_t pending_ = 0;
  std::int64_t next_tick_ = 0;  // wheel: first tick not yet delivered
  // Cache of the last deterministic tau(t): model id (-1: none) and send time.
  int last_id_ = -1;
  Micros last_t_ = 0;
  double last_delay_ = 0.0;
  // Cache of the last DeliveryTime (a function of send time and delay) and of the last
  // due time's tick.
  bool due_valid_ = false;
  Micros due_send_ = 0;
  double due_delay_ = 0.0;
  Micros due_ = 0;
  bool push_valid_ = false;
  Micros push_due_ = 0;
  std::int64_t push_tick_ = 0;
  // The wheel's buckets are lists, in submission order, threaded through one array of
  // queue entries (nodes_) with a free list: unlike a vector per bucket, whose capacity
  // each grows to the most that bucket ever held, the entries are made once for the
  // largest delay and reused.
  struct Node {
    Pending p{};
    int next = -1;  // next entry of its bucket, or of the free list; -1: none
  };
  struct Bucket {
    int head = -1, tail = -1;
  };
  std::vector<Bucket> wheel_;
  std::vector<Node> nodes_;
  int free_node_ = -1;
  std::size_t horizon_ticks_ = 0;  // wheel: most ticks a delivery waits
  std::priority_queue<Pending, std::vector<Pending>, std::greater<Pending>> heap_;
  // A delivery beyond the wheel, ordered by (tick, submission order).
  struct Far {
    std::int64_t tick;
    Pending p;
    bool operator>(const Far& o) const {
      return tick != o.tick ? tick > o.tick : p.order > o.p.order;
    }
  };
  static constexpr std::size_t kMaxWheel = std::size_t{1} << 16;  // buckets
  // Most queue entries made up front (2 MB; 4,096 payloads): a channel that may need more
  // (long delays on many links) grows as it fills, as it would without the reservation.
  static constexpr std::size_t kMaxReserved = std::size_t{1} << 16;
  std::priority_queue<Far, std::vector<Far>, std::greater<Far>> overflow_;
};

}  // namespace shoal

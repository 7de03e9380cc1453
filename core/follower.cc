#include "core/follower.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <type_traits>

#include "core/channel_model.h"

namespace shoal {

Follower::Follower(const Scenario& s, const Topology& topo, int id,
                   std::shared_ptr<const Environment> env, double duration_s,
                   std::shared_ptr<const Timeline> timeline)
    : id_(id),
      k1_(s.k1),
      k2_(s.k2),
      offset_(OffsetVec(s.offsets_m.at(id - 1))),
      period_us_(s.period_us()),
      timeout_us_(static_cast<Micros>(std::llround(s.neighbour_timeout_s * 1e6))),
      substeps_(Rk4Substeps(s)),
      tau_max_(s.vehicle.tau_max),
      disturbance_(s.disturbance.kind),
      disturbance_relative_(s.disturbance.relative_to_leader),
      env_(env ? std::move(env)
               : std::make_shared<const Environment>(s.leader, s.delay,
                                                     s.disturbance.relative_to_leader)),
      timeline_(s.events.empty() ? nullptr
                : timeline         ? std::move(timeline)
                                   : std::make_shared<const Timeline>(s)),
      current_(s.disturbance.current, Rng(s.seed, 0xC0FFEEULL, static_cast<std::uint64_t>(id))),
      slot_of_(topo.n() + 1, -1) {
  // Initial state: as given, or at the leader's start + offset, at rest.
  const FollowerInit& init = s.initial.at(id - 1);
  if (init.given) {
    x_.eta = init.eta;
    x_.nu = init.nu;
  } else {
    x_.eta = env_->leader_path().At(0.0).eta + offset_;
    x_.nu.setZero();
  }
  x_.eta(4) = WrapAngle(x_.eta(4));

  // In-neighbours: the leader (if pinned) and followers j with a_ij = 1.
  if (topo.Pinned(id)) {
    Slot sl;
    sl.sender = 0;
    sl.weight = topo.D()(id - 1, id - 1);
    slots_.push_back(sl);
  }
  for (int j : topo.Neighbours(id)) {
    Slot sl;
    sl.sender = j;
    sl.weight = topo.A()(id - 1, j - 1);
    sl.offset = OffsetVec(s.offsets_m.at(j - 1));
    slots_.push_back(sl);
  }
  for (std::size_t k = 0; k < slots_.size(); ++k) {
    slot_of_[slots_[k].sender] = static_cast<int>(k);
    if (timeline_) slots_[k].link = timeline_->LinkIndex(slots_[k].sender, id_);
  }

  history_ = StateHistory(HistoryCapacity(s, duration_s));

  out_.vehicle_id = id_;
  out_.seq = -1;
}

int Follower::Rk4Substeps(const Scenario& s) {
  const double ratio = ToSeconds(s.period_us()) / s.vehicle.integrator_step_s;
  const double steps = std::ceil(ratio * (1.0 - 1e-9));
  return static_cast<int>(std::clamp(steps, 1.0, static_cast<double>(kMaxRk4Substeps)));
}

std::int64_t Follower::HistoryCapacity(const Scenario& s, double duration_s) {
  // The history must reach back to the oldest send time still usable: the neighbour
  // timeout, plus the largest delay of any delay model, plus a margin of two periods.
  double max_delay = MaxDelaySeconds(s.delay);
  for (const LinkOverride& o : s.links) {
    if (o.delay) max_delay = std::max(max_delay, MaxDelaySeconds(*o.delay));
  }
  for (const ScenarioEvent& e : s.events) {
    if (e.delay) max_delay = std::max(max_delay, MaxDelaySeconds(*e.delay));
  }
  const double period_s = ToSeconds(s.period_us());
  const double span_s = s.neighbour_timeout_s + max_delay + 2.0 * period_s;
  // Computed in double: a delay of 1e9 s at 50 Hz is 5e10 samples, beyond int.
  const double span_samples = std::ceil(span_s / period_s) + 2.0;
  const double run_samples = static_cast<double>(s.final_tick(duration_s)) + 2.0;
  return static_cast<std::int64_t>(std::min(span_samples, run_samples));
}

void Follower::CountRejected(RxResult r) {
  if (r == RxResult::kOld) {
    ++counters_.msgs_dropped_old;
  } else if (r != RxResult::kAccepted) {
    ++counters_.msgs_dropped_invalid;
  }
}

int Follower::SumTerms(Micros now, bool* any_stale, Vec5* a) {
  // Protocol (10): one term per live neighbour, own state at the neighbour's send time,
  // summed in slot order as Protocol10 sums its terms.
  *a = Vec5::Zero();
  int count = 0;
  *any_stale = false;
  for (Slot& sl : slots_) {
    if (!sl.have || !sl.active) continue;
    if (now - sl.utime > timeout_us_) {
      if (!sl.stale) {
        sl.stale = true;
        ++counters_.neighbour_timeouts;
      }
      *any_stale = true;
      continue;
    }
    if (sl.utime > now) continue;
    // A neighbour's send time is usually a tick of this vehicle's own (no copy of the
    // sample then); else the own state is interpolated.
    HistorySample between;
    const HistorySample* own = history_.Exact(sl.utime);
    if (own == nullptr) {
      if (!history_.At(sl.utime, &between)) continue;
      own = &between;
    }
    AddProtocol10Term(k1_, k2_, offset_, sl.weight, sl.eta, sl.eta_dot, sl.offset, own->eta,
                      own->eta_dot, a);
    ++count;
  }
  counters_.active_neighbours = count;
  return count;
}

ForceJob* Follower::force_job() { return in_reset_ ? nullptr : &force_job_; }

void Follower::Forced() {
  Vec5 tau = Vec5::Zero();
  bool saturated = false;
  if (!in_reset_) {
    const ForceJob& j = force_job_;
    tau = j.tau;
    saturated = j.saturated;
    if (saturated) {
      ++counters_.saturated_ticks;
      for (int k = 0; k < 5; ++k) {
        counters_.saturated_channel[k] += std::abs(tau(k)) >= tau_max_(k) && tau(k) != j.wanted(k);
      }
    }
  }
  out_.tau = tau;
  if (saturated) out_.flags |= StateMsg::kFlagSaturated;
  force_ = tau + tau_dist_;
}

void Follower::Disturb(Micros now, const AttitudeTrig<double>& trig, Vec5* tau_dist,
                       Vec3* current) {
  // Uncertain factor, held over the control period.
  tau_dist->setZero();
  current->setZero();
  if (disturbance_ == DisturbanceKind::kPaperExample2) {
    // f(eta(t - tau(t)), eta_dot(t - tau(t))) in eta'': as a force, M J^{-1} f.
    const Environment::DelayedLeader dl = env_->At(now, &leader_anchor_);
    HistorySample past;
    if (!history_.At(now - dl.delay_us, &past)) past = history_.Oldest();
    // The delayed state moves a few millimetres and milliradians per tick: its sines and
    // cosines are carried from the last tick's (std::sin and cos were 14 % of shoal sim).
    delayed_y_.Set(past.eta(1));
    delayed_z_.Set(past.eta(2));
    delayed_psi_.Set(past.eta(4));
    Vec5 f = PaperExample2F(delayed_y_.sin(), delayed_z_.cos(), delayed_psi_.sin(), past.eta_dot);
    if (disturbance_relative_) f -= dl.f0;
    *tau_dist = model_.MTimes(FossenModel::JInvTimes(trig, f));
  } else if (disturbance_ == DisturbanceKind::kOceanCurrent) {
    *current = current_.Step(ToSeconds(period_us_));
  }
}

bool Follower::SamePlant(const Follower& o) const {
  static_assert(std::is_trivially_copyable_v<RemusParams>);
  return substeps_ == o.substeps_ && period_us_ == o.period_us_ &&
         std::memcmp(&model_.params(), &o.model_.params(), sizeof(RemusParams)) == 0;
}

void Follower::Integrated() {
  trig_age_ = (trig_age_ + 1) % kTrigRefreshTicks;  // the heading's wrap below keeps sin, cos
  x_.eta(4) = WrapAngle(x_.eta(4));
  ++counters_.ticks;
  if (!x_.eta.allFinite() || !x_.nu.allFinite() || std::abs(x_.eta(3)) > 80.0 * kPi / 180.0) {
    diverged_ = true;
  }
}

void Follower::FollowTimeline(Micros now) {
  timeline_now_ = now;
  // A window that starts is a new reset, even right after another one.
  const Micros start = timeline_->ResetStart(id_, now);
  const bool reset = start != Timeline::kNoReset;
  if (reset && start != reset_at_) {
    // The controller restarts with nothing: no neighbour data, no own past.
    for (Slot& sl : slots_) {
      sl.have = false;
      sl.stale = false;
    }
    history_.Clear();
  }
  reset_at_ = start;
  in_reset_ = reset;
  if (timeline_->switches_topology()) {
    for (Slot& sl : slots_) {
      const bool active = sl.link >= 0 && timeline_->LinkActive(sl.link, now);
      // A link that enters the topology in force starts with nothing, as at the run's
      // start: the message kept from before the switch would be counted as a timeout and
      // flag the state stale, or, younger than the timeout, be used as the newest.
      if (active && !sl.active) {
        sl.have = false;
        sl.stale = false;
      }
      sl.active = active;
    }
  }
}

const StateMsg& Follower::Tick(Micros now) {
  const StateMsg& out = Control(now);
  if (ForceJob* j = force_job()) {
    SaturatedFeedbackLineariseMany(model_, &j, 1);
  }
  Forced();
  Integrate(model_, force_, current_ned_, ToSeconds(period_us_), substeps_, &x_, &control_trig_,
            &trig_);
  Integrated();
  return out;
}

const StateMsg& Follower::Control(Micros now) {
  BeginTick(now);
  if (trig_age_ == 0) trig_ = AttitudeTrig<double>(x_.eta);
  control_trig_ = trig_;
  const AttitudeTrig<double>& trig = control_trig_;
  // eta_dot is computed into the history's newest sample, not copied there (see EtaDotTo).
  HistorySample* newest = history_.Append(now);
  Vec5 own_eta_dot;  // only if Control were asked twice for one time
  Vec5& eta_dot = newest ? newest->eta_dot : own_eta_dot;
  FossenModel::EtaDotTo(trig, x_.nu, &eta_dot);
  if (newest) newest->eta = x_.eta;

  bool any_stale = false;
  Vec5 a = Vec5::Zero();
  if (in_reset_) {
    ++counters_.reset_ticks;
    counters_.active_neighbours = 0;
  } else {
    SumTerms(now, &any_stale, &a);
    // The inner loop's input; the force comes back by Forced().
    force_job_.trig = trig;
    force_job_.nu = x_.nu;
    force_job_.a = a;
    force_job_.tau_max = tau_max_;
  }
  Disturb(now, trig, &tau_dist_, &current_ned_);

  out_.seq += 1;
  out_.utime = now;
  out_.eta = x_.eta;
  out_.nu = x_.nu;
  out_.eta_dot = eta_dot;
  out_.accel_cmd = a;
  out_.flags = (any_stale ? StateMsg::kFlagStaleNeighbour : 0) |
               (in_reset_ ? StateMsg::kFlagControllerReset : 0);
  return out_;
}

}  // namespace shoal

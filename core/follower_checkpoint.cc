// Checkpoint and resume of a Follower (core/follower.h): a restarted vehicle process goes
// on from the state its predecessor last published.
#include "core/follower.h"

namespace shoal {

Follower::Checkpoint Follower::MakeCheckpoint() const {
  Checkpoint c;
  c.published = out_;
  c.eta = x_.eta;
  c.nu = x_.nu;
  c.counters = counters_;
  c.diverged = diverged_;
  c.trig = trig_;
  c.trig_age = trig_age_;
  c.delayed[0] = delayed_y_.carried();
  c.delayed[1] = delayed_z_.carried();
  c.delayed[2] = delayed_psi_.carried();
  return c;
}

void Follower::Resume(const Checkpoint& c) {
  x_.eta = c.eta;
  x_.nu = c.nu;
  out_ = c.published;
  out_.vehicle_id = id_;
  counters_ = c.counters;
  diverged_ = c.diverged;
  trig_ = c.trig;
  trig_age_ = c.trig_age >= 0 && c.trig_age < kTrigRefreshTicks ? c.trig_age : 0;  // 0: afresh
  delayed_y_.Restore(c.delayed[0]);
  delayed_z_.Restore(c.delayed[1]);
  delayed_psi_.Restore(c.delayed[2]);
  // The ocean current is a random process stepped once per tick: drawn again as far as
  // the checkpoint's tick, it goes on with the numbers the uninterrupted run would draw.
  if (disturbance_ == DisturbanceKind::kOceanCurrent) {
    for (std::int64_t k = 0; k < counters_.ticks; ++k) current_.Step(ToSeconds(period_us_));
  }
  for (Slot& sl : slots_) {
    sl.have = false;
    sl.stale = false;
  }
  history_ = StateHistory(history_.capacity());
  if (out_.seq >= 0) history_.Push(HistorySample{out_.utime, out_.eta, out_.eta_dot});
}

}  // namespace shoal

// One follower UUV: protocol (10) + feedback linearisation on its Fossen plant.
// The same object runs inside shoal sim and inside the vehicle process, which is what
// makes a lockstep SIL run equal to shoal sim.
#pragma once

#include <limits>
#include <memory>
#include <vector>

#include "core/control.h"
#include "core/fossen.h"
#include "core/disturbance.h"
#include "core/history.h"
#include "core/scenario.h"
#include "core/state_msg.h"
#include "core/timeline.h"
#include "core/topology.h"

namespace shoal {

struct FollowerCounters {
  std::int64_t ticks = 0;
  std::int64_t msgs_received = 0;
  std::int64_t msgs_dropped_invalid = 0;  // non-finite, unknown sender
  std::int64_t msgs_dropped_old = 0;      // replayed or out of order
  std::int64_t neighbour_timeouts = 0;
  std::int64_t saturated_ticks = 0;
  std::int64_t saturated_channel[5] = {0, 0, 0, 0, 0};
  std::int64_t reset_ticks = 0;          // ticks stepped with the controller reset
  std::int64_t msgs_ignored_reset = 0;   // received while the controller was reset
  int active_neighbours = 0;
};

enum class RxResult { kAccepted, kUnknownSender, kNonFinite, kOld };

class Follower {
 public:
  /// Follower `id` (1..n) of a validated scenario.
  /// `env` may be shared between the followers of one process; null builds a private one.
  /// `duration_s`: the run's length (< 0: the scenario's); it bounds the history's size.
  /// `topo`: UnionTopology(s) (a slot for every neighbour any topology gives it).
  /// `timeline`: the scenario's events, shared between the followers of one process; null
  /// builds a private one when the scenario has events.
  Follower(const Scenario& s, const Topology& topo, int id,
           std::shared_ptr<const Environment> env = nullptr, double duration_s = -1.0,
           std::shared_ptr<const Timeline> timeline = nullptr);

  /// Samples the history of a follower of `s` holds in a run of `duration_s` (< 0: the
  /// scenario's): enough to reach back over the neighbour timeout, the largest delay and
  /// two periods, but never more than the run has ticks (plus two), since a history that
  /// is never full gives the same answers as a larger one.
  static std::int64_t HistoryCapacity(const Scenario& s, double duration_s = -1.0);
  /// RK4 steps per control period: the period split into whole steps no longer than
  /// vehicle.integrator_step_s (a ratio within 1e-9 of a whole number counts as that
  /// number, so 0.1 / 0.02 is 5 steps, not 6). The loader bounds it (kMaxRk4Substeps).
  static int Rk4Substeps(const Scenario& s);

  int id() const { return id_; }

  /// Offers a message received on SHOAL_RX_<id>. Only a finite message from an
  /// in-neighbour (or the leader, if pinned) that is newer than the one held is kept;
  /// everything else is counted and ignored. A controller in reset (a controller_reset
  /// event) keeps nothing either. Never throws, never allocates.
  RxResult Receive(const StateMsg& m);
  /// What Receive would do with `m` now, without keeping or counting it (lockstep holds
  /// messages until they are due).
  RxResult Check(const StateMsg& m) const;
  /// Counts a rejection as Receive would (unknown sender / non-finite / old).
  void CountRejected(RxResult r);

  /// Applies the scenario's timeline at tick `now` (a controller reset starting or ending,
  /// the topology in force) before the tick's deliveries are received; Tick(now) does it
  /// if it was not done. Without events it does nothing.
  void BeginTick(Micros now) {
    if (timeline_ && timeline_now_ != now) FollowTimeline(now);
  }

  /// One control tick at `now`: records the current state, computes protocol (10) from
  /// the newest data of each live neighbour of the topology in force, feedback-linearises
  /// and saturates, returns the message to publish (the state at `now`), then integrates
  /// the plant to now + period. In a controller reset window the controller forgets its
  /// neighbour data and own history at the window's first tick and commands zero force
  /// throughout (the plant and its disturbances go on). Never throws, never allocates.
  const StateMsg& Tick(Micros now);
  /// Tick() in parts, for a caller that steps many followers' inner loops and plants at
  /// once, in vector lanes (SaturatedFeedbackLineariseMany, IntegrateMany). Tick(now) is
  /// exactly:
  ///   Control(now): the tick up to the inner loop; returns the message, whose tau and
  ///     saturation flag are filled in by Forced();
  ///   force_job(): the inner loop's feedback linearisation to run (null in a controller
  ///     reset, which commands no force);
  ///   Forced(): the force's accounting once that job ran;
  ///   plant_job(): the integration over the period, to run;
  ///   Integrated(): the end of the tick once the integration ran.
  const StateMsg& Control(Micros now);
  ForceJob* force_job();
  void Forced();
  // Defined here so that the caller builds the job in place: a job returned from another
  // translation unit is written by 8-byte stores and read back by 16-byte loads, which
  // the CPU cannot forward from the stores (a stall of its own per follower and tick).
  PlantJob plant_job() {
    PlantJob j;
    j.x = &x_;
    j.tau = force_;
    j.current_ned = current_ned_;
    j.trig = &control_trig_;
    j.trig_out = &trig_;
    return j;
  }
  void Integrated();
  /// True if this follower's plant integrates with the same model, period and substeps as
  /// `o`'s (so that both can be stepped in one IntegrateMany call).
  bool SamePlant(const Follower& o) const;
  int substeps() const { return substeps_; }
  const FossenModel& model() const { return model_; }

  const PlantState& state() const { return x_; }
  const FollowerCounters& counters() const { return counters_; }
  /// True once the state became non-finite or |pitch| exceeded 80 deg (J singular at 90).
  bool diverged() const { return diverged_; }

  // Checkpoint and resume (core/follower_checkpoint.cc): what a restarted vehicle process
  // needs to go on from its last tick (a fixed set of numbers, which the vehicle process
  // writes to its checkpoint file, runtime/checkpoint.h).
  struct Checkpoint {
    StateMsg published;  // the message the last Tick returned
    Vec5 eta, nu;        // the plant state after that Tick's integration (at utime + period)
    FollowerCounters counters;
    bool diverged = false;
    /// The attitude's sines and cosines as carried from tick to tick, and their age: a
    /// resumed follower carries them on as the uninterrupted one does, to the bit.
    AttitudeTrig<double> trig{Vec5::Zero()};
    int trig_age = 0;
    /// The sines and cosines of the uncertain factor's delayed state, carried likewise
    /// (y, z, psi).
    CarriedSinCos::Carried delayed[3];
  };
  /// The state after the last Tick (published.seq = -1 before any).
  Checkpoint MakeCheckpoint() const;
  /// Goes on from `c`, taken of a follower built from the same scenario, id and run
  /// length: the plant state, the message sequence, the counters and the ocean current's
  /// random process are restored. Neighbour data is not (a restarted process has lost
  /// it): every neighbour is waited for again. The own history starts with the published
  /// state. The next Tick is the one at published.utime + period.
  void Resume(const Checkpoint& c);

 private:
  struct Slot {
    int sender = 0;
    double weight = 1.0;
    Vec5 offset = Vec5::Zero();
    bool have = false;
    bool stale = false;
    bool active = true;  // its link is in the topology in force
    int link = -1;       // index of its link in the timeline
    // Of the newest accepted message, what protocol (10) and the checks use.
    Micros utime = 0;
    std::int32_t seq = 0;
    Vec5 eta = Vec5::Zero();
    Vec5 eta_dot = Vec5::Zero();
  };

  /// Applies the timeline at `now`: the reset window (entering it clears the memory) and
  /// the topology in force (which slots are active).
  void FollowTimeline(Micros now);

  // The steps of Tick, in order.
  /// Protocol (10)'s sum over the live neighbours into *a (Protocol10 of their terms, to
  /// the bit); returns their count. Marks (and counts) neighbours whose newest message is
  /// older than the timeout.
  int SumTerms(Micros now, bool* any_stale, Vec5* a);
  /// The uncertain factor as a force, or the ocean current, held over the period.
  void Disturb(Micros now, const AttitudeTrig<double>& trig, Vec5* tau_dist, Vec3* current);

  int id_;
  double k1_, k2_;
  Vec5 offset_;
  Micros period_us_;
  Micros timeout_us_;
  int substeps_;
  Vec5 tau_max_;
  DisturbanceKind disturbance_;
  bool disturbance_relative_;
  std::shared_ptr<const Environment> env_;
  std::shared_ptr<const Timeline> timeline_;  // null: no events
  Micros timeline_now_ = std::numeric_limits<Micros>::min();  // tick it was applied at
  Micros reset_at_ = Timeline::kNoReset;  // start of the reset window in force
  bool in_reset_ = false;
  OceanCurrent current_;
  FossenModel model_;

  PlantState x_;
  // The attitude's sines and cosines at x_: carried from one tick's integration to the
  // next (ShiftTrig, exact to rounding), computed afresh every kTrigRefreshTicks ticks so
  // that rounding cannot accumulate.
  static constexpr int kTrigRefreshTicks = 50;
  AttitudeTrig<double> trig_{Vec5::Zero()};
  int trig_age_ = 0;  // 0: compute afresh
  // What Control() leaves for the integration: the trig at the tick's state, the force
  // (control plus uncertain factor) and the ocean current, held over the period.
  AttitudeTrig<double> control_trig_{Vec5::Zero()};
  // sin y, cos z, sin psi of the state at the uncertain factor's delayed time.
  CarriedSinCos delayed_y_, delayed_z_, delayed_psi_;
  // The leader's helix anchor for the factor, when the environment is not warmed for this
  // tick (a vehicle process: its own environment).
  LeaderPath::HelixAnchor leader_anchor_;
  ForceJob force_job_;
  Vec5 tau_dist_ = Vec5::Zero();
  Vec5 force_ = Vec5::Zero();
  Vec3 current_ned_ = Vec3::Zero();
  StateHistory history_;
  std::vector<Slot> slots_;
  std::vector<int> slot_of_;  // sender id -> slot index, -1 if not a neighbour
  StateMsg out_;
  FollowerCounters counters_;
  bool diverged_ = false;
};

// Receive and Check are defined here so that a caller in another file (Swarm::Step, for
// every delivery) inlines them.
inline RxResult Follower::Check(const StateMsg& m) const {
  if (m.vehicle_id < 0 || m.vehicle_id >= static_cast<int>(slot_of_.size()) ||
      slot_of_[m.vehicle_id] < 0) {
    return RxResult::kUnknownSender;
  }
  if (!m.AllFinite()) return RxResult::kNonFinite;
  const Slot& sl = slots_[slot_of_[m.vehicle_id]];
  if (sl.have && (m.utime <= sl.utime || m.seq <= sl.seq)) return RxResult::kOld;
  return RxResult::kAccepted;
}

inline RxResult Follower::Receive(const StateMsg& m) {
  if (in_reset_) {
    ++counters_.msgs_ignored_reset;
    return RxResult::kAccepted;  // a valid message; the reset controller drops it
  }
  const RxResult r = Check(m);
  if (r != RxResult::kAccepted) {
    CountRejected(r);
    return r;
  }
  Slot& sl = slots_[slot_of_[m.vehicle_id]];
  sl.utime = m.utime;
  sl.seq = m.seq;
  sl.eta = m.eta;
  sl.eta_dot = m.eta_dot;
  sl.have = true;
  sl.stale = false;
  ++counters_.msgs_received;
  return RxResult::kAccepted;
}

}  // namespace shoal

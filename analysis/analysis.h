// Metrics of a run from its RunData: formation (core/metrics, the definitions of
// shoal sim), channel ground truth, process health. Definitions: docs/analyze.md.
//
// For the renderer, per vehicle: RunData::vehicles[id].samples (t = utime, eta, nu, ...)
// and, for followers, FollowerAnalysis::errors aligned with those samples; per channel
// decision: RunData::channel_events (send time, sender, receiver, status, drawn delay)
// and ChannelAnalysis::configured_delay_s aligned with them (realised delay =
// deliver_utime - send_utime for delivered events).
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "analysis/run_data.h"
#include "core/metrics.h"

namespace shoal {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// Order statistics of a sample (nearest rank: the value at rank round(q (count - 1)) of
/// the sorted sample). NaN when empty.
struct Quantiles {
  std::int64_t count = 0;
  double min = kNaN, p50 = kNaN, p99 = kNaN, max = kNaN, mean = kNaN;
};
/// Reorders *v.
Quantiles QuantilesOf(std::vector<double>* v);
Quantiles QuantilesOf(double* begin, double* end);

struct FollowerAnalysis {
  int id = 0;
  /// Aligned with RunData::vehicles[id].samples; NaN where the leader has no sample at
  /// the same utime.
  std::vector<FormationErrors> errors;
  std::int64_t compared = 0;  // samples with a leader sample at the same utime
  bool converged = false;
  double convergence_time_s = kNaN;  // this follower alone (same rule as the swarm's)
  FormationErrors final_errors;      // at its last compared sample
  double max_position_error_m = kNaN;
  // From the state flags (independent of the health reports).
  std::int64_t samples = 0;
  std::int64_t saturated_ticks = 0;
  std::int64_t stale_ticks = 0;   // samples with FLAG_STALE_NEIGHBOUR
  std::int64_t stale_events = 0;  // times the flag went from clear to set
  double saturation_fraction = kNaN;
};

struct LinkAnalysis {
  int from = 0, to = 0;
  bool in_scenario = false;  // a topology of the scenario (UnionTopology) has this link
  std::int64_t sent = 0, delivered = 0, dropped_loss = 0, dropped_queue = 0, dropped_invalid = 0;
  std::int64_t dropped_range = 0;  // acoustic: receiver beyond max_range_m (counted as sent)
  std::int64_t skipped_busy = 0;   // the sender's modem was busy: never transmitted, not sent
  // Timeline ([[event]]) statuses: a silent sender never transmitted (not sent); a link
  // down or a deaf receiver drops a sent message.
  std::int64_t skipped_silent = 0, dropped_link_down = 0, dropped_deaf = 0;
  Quantiles realised_delay_s;      // deliver - send, delivered only
  Quantiles delay_error_s;         // realised - configured tau(send time)
  Quantiles age_at_use_s;          // receiver tick time - send time of the newest message held
  std::int64_t ticks_stale = 0;    // receiver ticks whose newest message was older than the timeout
  std::int64_t ticks_before_first = 0;  // receiver ticks before the first delivery
};

struct ChannelAnalysis {
  std::int64_t sent = 0, delivered = 0, dropped = 0;
  std::int64_t dropped_loss = 0, dropped_queue = 0, dropped_invalid = 0, dropped_range = 0;
  std::int64_t skipped_busy = 0;  // decisions "modem busy": not in sent
  std::int64_t skipped_silent = 0;  // decisions "sender silent": not in sent
  std::int64_t dropped_link_down = 0, dropped_deaf = 0;  // in dropped
  Quantiles realised_delay_s, delay_error_s, age_at_use_s;
  /// Events whose drawn delay differs (> 1 ns) from the scenario's deterministic tau(t)
  /// (the model in force at the send time: a channel event's on its links and window, the
  /// [channel] one otherwise): the emulator ran another delay model than the scenario says.
  std::int64_t model_mismatches = 0;
  std::int64_t unknown_links = 0;  // events on links no topology of the scenario has
  /// Events at times the run cannot have produced (ChannelEventTimeOf): counted here, left
  /// out of every other figure (counts, delays, ages, mismatches, links).
  std::int64_t events_damaged = 0;
  std::int64_t events_sent_impossible = 0;       // sent at a negative time or after the end
  std::int64_t events_delivered_impossible = 0;  // delivered before sent or after the last
                                                 // possible delivery
  /// Real time: the emulator's release error p99 (release time - due time) from its last
  /// health report, as shoal run reports it; 0 in lockstep and shoal sim (no emulator
  /// health or exact tick releases).
  double release_error_p99_s = 0.0;
  /// Configured tau(send time) of each event, aligned with RunData::channel_events: the
  /// scenario's delay model of that link for none/constant/sinusoid; the drawn delay_s for
  /// uniform jitter (the scenario only gives its distribution) or without a scenario;
  /// NaN for a damaged event.
  std::vector<double> configured_delay_s;
  std::vector<LinkAnalysis> links;  // sorted by (from, to)
};

/// Channel decision statuses (channel_event_t::STATUS_*, ChannelDecision): 0 delivered ..
/// 8 receiver deaf.
constexpr int kChannelStatuses = 9;
/// A status' key in the JSON counters ("delivered", "dropped_loss", ... "dropped_deaf").
const char* ChannelStatusKey(int status);

/// One [[event]] of the scenario's timeline and what the run did around it (docs/analyze.md,
/// "Events").
struct EventAnalysis {
  int index = 0;  // in Scenario::events
  EventKind kind = EventKind::kLinkDown;
  double at_s = kNaN;
  double end_s = kNaN;         // the event's end (ScenarioEvent::end_s), at most the run's end
  bool ends_in_run = false;    // the event ends before the run's end
  std::string affects;         // what it applies to, as text ("links 0->1, 2->3", ...)
  /// From at_s until re-convergence (or the horizon when it does not re-converge): the
  /// largest worst-follower position and velocity error, at complete samples.
  double max_position_error_m = kNaN;
  double max_velocity_error_mps = kNaN;
  int max_position_follower = 0;  // the follower with that position error
  double max_position_time_s = kNaN;
  double reference_s = kNaN;  // end_s if the event ends in the run, else at_s
  double horizon_s = kNaN;    // the next event's start after reference_s, else the run's end
  bool reconverged = false;
  double reconverged_at_s = kNaN;
  double time_to_reconverge_s = kNaN;  // reconverged_at_s - reference_s
  /// Channel decisions of the links it affects in [at_s, end_s) by status (index = status;
  /// a vehicle_deaf event counts by due time, every other by send time).
  std::int64_t decisions[kChannelStatuses] = {};
};

struct ProcessAnalysis {
  int id = 0;  // vehicle id, -1 channel emulator
  std::int64_t reports = 0;
  HealthRecord last;  // the last report in the log (figures since the process started)
};

/// The summary shoal run prints from its log; shoal analyze prints it too (same keys).
struct RunSummary {
  bool converged = false;
  double convergence_time_s = -1.0;  // -1 if not converged
  FormationErrors final_worst;       // worst follower at the last complete sample
  double max_position_error_m = 0.0;
  double sim_time_s = 0.0;           // leader time of the last complete sample
  std::int64_t states = 0;           // valid vehicle states in the log
  std::int64_t delivered = 0, dropped = 0;
  double lateness_p99_s = 0.0;       // worst process (vehicles and leader), last health report
  std::int64_t overruns = 0;         // sum over processes, last health reports
  double release_error_p99_s = 0.0;  // the emulator's (real time)
};

/// The times a vehicle state of `run` can have: [0, limit_us]. From what the run declares
/// (the scenario's duration and period) where the log carries it, else from what most
/// vehicles show; never from the largest time in the log, which one damaged or forged
/// state can set to anything.
struct StateTimeBounds {
  /// The last possible state time, and send time of a channel event. -1: no state is
  /// possible (and the channel events' end is unknown).
  Micros limit_us = -1;
  Micros expected_end_us = -1;  // the last tick the run should have recorded
  bool declared = false;        // limit from the scenario's run.duration_s
  /// The last possible delivery time of a channel event (-1: unknown, when limit_us is):
  /// a message sent at limit_us, delayed by the largest delay any link of the scenario can
  /// draw (rounded up to whole microseconds), delivered at the first control tick after
  /// that (so one period more). Without a scenario the largest delay is unknown and the
  /// run's own length (limit_us) stands in for it.
  Micros deliver_limit_us = -1;
};

/// A process restarted in place of one that died (shoal run --restart on-failure), from
/// its "restarted" status.
struct RestartAnalysis {
  int id = 0;           // vehicle id (0 leader)
  Micros utime = 0;     // the first tick it stepped after the restart
  std::string message;  // why, and from which state it resumed
  /// Its ticks before that one that the log has no state for: the ticks it was down for
  /// (real time steps them without publishing). 0 in lockstep, which steps every tick.
  std::int64_t states_missing = 0;
};

struct RunAnalysis {
  std::string mode;  // "sim", "lockstep", "realtime" or "unknown", inferred from the log
  Micros period_us = 0;
  bool has_formation = false;  // scenario (offsets) and leader states available
  RunSummary summary;
  std::int64_t complete_samples = 0;  // times with the leader and every follower
  std::vector<FormationErrors> final_errors;  // per follower at the last complete sample
  std::vector<FollowerAnalysis> followers;    // index i - 1 for follower i
  int diverged_follower = 0;  // first follower with a non-finite state or |pitch| > 80 deg
  ChannelAnalysis channel;
  std::vector<EventAnalysis> events;       // per [[event]] of the scenario, in its order
  std::vector<ProcessAnalysis> processes;  // sorted by id
  std::int64_t ticks = 0;                  // clock ticks in the log (else leader samples)
  std::int64_t states_expected = 0;        // (expected last tick + 1) * (n + 1)
  /// States whose time the run cannot have produced (StateTimeBoundsOf): negative, or
  /// after the run's end. Counted here, left out of every metric.
  std::int64_t states_damaged = 0;
  std::int64_t states_negative_time = 0, states_after_end = 0;
  StateTimeBounds bounds;  // of the states and channel events: StateTimeBoundsOf(run)
  double end_s = kNaN;  // the last time a state may have (NaN: no state in the log)
  double wall_time_s = kNaN;  // recording span if the log's timestamps are wall clock
  bool interrupted = false;   // a run-level status said "interrupted"
  std::vector<std::string> problems;  // failed / vehicle_lost statuses
  std::vector<RestartAnalysis> restarts;   // in log order, one per restart
  std::int64_t states_missing_in_restarts = 0;  // sum of their states_missing
  // The leader's path.
  double leader_path_length_m = kNaN;
  Vec3 leader_start_m = Vec3::Constant(kNaN), leader_end_m = Vec3::Constant(kNaN);
};

StateTimeBounds StateTimeBoundsOf(const RunData& run);

/// Whether a channel event's times are possible in a run with bounds `b`. Sent: in
/// [0, limit_us]. Delivered (status delivered only; a drop has no delivery time): in
/// [send_utime, deliver_limit_us]. Where a limit is unknown (-1) only the sign and the
/// order of the times are checked. The one rule for shoal analyze and shoal render.
enum class EventTime { kPossible, kSendImpossible, kDeliveryImpossible };
EventTime ChannelEventTimeOf(const ChannelEventRecord& e, const StateTimeBounds& b);

/// Removes from `run` the states outside StateTimeBoundsOf(run) and the channel events at
/// impossible times (ChannelEventTimeOf): for a plot, whose axes one state at 9e12 s or one
/// delivery at 1e9 s would stretch. Says so in run->warnings. Returns how many.
std::int64_t DropImpossibleTimes(RunData* run);

/// Metrics of the states and channel events within StateTimeBoundsOf(run); the others are
/// counted only.
RunAnalysis AnalyseRun(const RunData& run);

/// shoal run's summary of its own log, with the given scenario. False only if the log
/// cannot be opened; a log without Shoal data gives an all-zero summary.
bool SummariseRunLog(const std::string& path, const Scenario& s, RunSummary* out);

}  // namespace shoal

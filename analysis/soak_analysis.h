// The judgement of a soak run: one long shoal run whose phases step a parameter (the
// campaign spec's [soak]). Reads the run's log (LoadRunLog, AnalyseRun), its
// <log>.d/resources.csv (docs/run.md) and its shoal run --json report, and gives
// per-minute rows, per-phase metrics and a verdict with a sentence per reason.
//
// Definitions (mission time t; minute m covers [60 m, 60 (m + 1)); the run's last state
// time counts in the last minute and the last phase when they end there):
// - A complete sample: a time at which the leader and every follower have a state. Its
//   worst position error is the largest follower position error; it is within tolerance
//   when that is within the scenario's metrics.position_tol_m. Position only: the
//   velocity tolerance of `converged` (FormationMetrics) would fail a phase for the
//   velocity ripple a delay step leaves while the formation holds its shape.
// - Lateness p99 of a window: the p99 of the loop lateness samples of the vehicles and the
//   leader, from the health reports within the window: each report's histogram of the
//   samples since that process's previous report (health2_t, 1 Hz, so the window's
//   samples from about a second before it starts up to its last report), summed; the
//   upper edge of the bin holding the p99 rank, capped by the largest sample: at most one
//   bin (9 %) above the exact p99 of those samples between 1 us and 1.049 s (below, up to
//   1 us; beyond, the window's largest sample). A log of health_t (older builds, no
//   histogram) gives the largest since-start p99 reported within the window instead,
//   which a long history dilutes. release_error_p99_s: as lateness, of the channel
//   emulator's reports (its release error samples).
// - Overruns of a window: the increase of each process's cumulative count over the
//   reports within the window (a restarted process counts from its own start), summed.
// - delay_error_p99_s of a window: p99 (nearest rank) of realised - configured delay of the
//   delivered channel events sent within it (ChannelAnalysis::configured_delay_s; tick
//   quantised in lockstep, so within [0, one period)).
// - States: distinct vehicle states in the log with times in the window; expected: the
//   control ticks in the window up to the run's expected end, times (followers + 1).
// - Per process, from resources.csv: at the end of minute m, the first sample at or after
//   that time (the last sample for the run's last minute); CPU % = CPU seconds over wall
//   seconds between that sample and the one at the end of the previous minute (the
//   first sample for minute 0), null when the pid changed between them (a restart).
// - Re-converged: every complete sample in [start + settle_s, end) is within tolerance
//   (and there is one). Memory growth: each process's largest RSS after the first
//   phase's end against its RSS at that end (the first sample at or after it); with one
//   phase, after the end of its settle time. No sample to judge by fails the verdict.
// The verdict fails on: a process that failed, was stopped, restarted or an interrupted
// run (the report's all_processes_ok, restarts); lost states (log_complete false, or a
// minute with fewer states than expected); RSS growth beyond targets.memory_growth_max;
// real time only: a phase with more overruns than targets.overruns_max, a phase's lateness
// p99 beyond targets.lateness_p99_max_s, or its delay error p99 or release error p99 beyond
// targets.delay_error_p99_max_s (shoal run reports the release error as
// channel.delay_error_p99_s); a phase that does not re-converge or misses a criterion.
// - The machine's own stalls (real time, when shoal run's witness watched: SoakInput's
//   machine_stalls): overlapping stalls (each CPU's thread sees a stall of the whole
//   machine) are one, as long as the longest of them (L below); a stall is taken to have
//   begun up to the witness's period (2 ms) before the deadline it dates it from. Each
//   health report covers the time since its process's previous report; a stall
//   overlapping that time accounts, in that process and once over all its reports, for
//   - ticks of a loop (the leader, a vehicle) late beyond the lateness target: up to
//     ceil(L / period) + 1 (the tick due just before it, still waiting for a CPU, and those
//     due during it) if L is at least half the target;
//   - overruns of a loop: up to as many, if L is at least half a period;
//   - the emulator's releases late beyond the delay target: up to (L + 2 ms) times the
//     report's release rate, if L is at least half the target;
//   each tick or release late by at most 2 L (the stall covering at least half of what it
//   lost, as shoal run's verdict asks: once the machine runs again every loop it held
//   queues for the CPUs), judged by its histogram bin's upper edge (or the report's
//   largest sample); the latest samples are matched first, each to a stall that could
//   have made it that late. A delivered message's delay error beyond the target is
//   accounted for when one stall covers at least half of its lateness (from its due time
//   on). A phase's timing is machine-limited when it missed a timing target but meets every
//   one without what the stalls account for: the p99s of the samples left, the overruns
//   left. A stall gives its ticks once over the whole run, so a stall across two phases
//   too. The verdict still fails on it; the phase (and the verdict, when nothing else
//   failed) says that the machine accounts for the miss. A [pass] criterion on a timing
//   metric is judged on the figures as measured. A phase's `machine` counts the stalls
//   from the earliest time its reports cover (a second before it) to its end; it is not
//   complete when the witness's threads had run out of room for stalls (kStallRoom each)
//   before the phase's end.
#pragma once

#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace shoal {

/// One phase of the soak run: mission time [start_s, end_s); `label` says its value
/// ("channel.delay.base_s = 0.5").
struct SoakPhase {
  double start_s = 0.0, end_s = 0.0;
  std::string label;
};

/// A pass criterion on a phase metric (keys of SoakPhaseResult::metrics): equality with
/// `equals` (when not null), and/or bounds.
struct SoakCriterion {
  std::string metric;
  nlohmann::json equals;  // null: no equality
  std::optional<double> min, max;
};

/// The campaign's [pass] table as JSON ({"max_position_error_m": {"max": 1}, "reconverged":
/// true}): one criterion per key. False with *error on a value of another shape.
bool ParseSoakCriteria(const nlohmann::json& pass, std::vector<SoakCriterion>* out,
                       std::string* error);

struct SoakTargets {
  double lateness_p99_max_s = 0.002;     // real time only
  double delay_error_p99_max_s = 0.001;  // real time only
  double memory_growth_max = 0.01;       // relative RSS growth after the first phase
  long long overruns_max = 0;            // real time only: overrun ticks a phase may have
};

/// A stall of the whole machine that shoal run's witness saw (launcher/machine_witness.h):
/// from `start_s` (mission time) for `length_s`.
struct SoakStall {
  double start_s = 0.0, length_s = 0.0;
};

struct SoakInput {
  std::string log;            // the run's LCM log
  std::string key_file;       // its key (<log>.key); "" for that default (LoadOptions)
  std::string resources_csv;  // <log>.d/resources.csv; "" when not sampled (no judgement)
  nlohmann::json report;      // the run's shoal run --json report
  std::vector<SoakPhase> phases;  // in time order
  double settle_s = 0.0;
  std::vector<SoakCriterion> criteria;
  SoakTargets targets;
  std::string engine = "lockstep";  // "lockstep" or "realtime"
  bool machine_watched = false;     // the witness watched the whole run
  std::vector<SoakStall> machine_stalls;  // what it saw, every CPU's
  /// The witness kept every stall it saw up to this time (mission time): after it, a
  /// thread that ran out of room dropped some. Phases ending later say so.
  double machine_complete_until_s = std::numeric_limits<double>::infinity();
};

struct SoakProcessUse {
  std::string name;
  int pid = 0;
  double rss_kib = 0.0;
  std::optional<double> cpu_percent;
};

struct SoakMinute {
  int minute = 0;
  double start_s = 0.0, end_s = 0.0;
  std::optional<double> worst_position_error_m;  // none: no complete sample
  double lateness_p99_s = 0.0, release_error_p99_s = 0.0;
  long long overruns = 0;
  std::optional<double> delay_error_p99_s;  // none: no delivery sent in the minute
  long long states = 0, states_expected = 0;
  std::vector<SoakProcessUse> processes;
};

struct SoakPhaseResult {
  int index = 0;
  SoakPhase phase;
  /// reconverged, reconverged_at_s, final_position_error_m, max_position_error_m,
  /// delay_error_p99_s, release_error_p99_s, lateness_p99_s, overruns, states,
  /// states_expected (null where the phase has no such data).
  nlohmann::ordered_json metrics;
  bool pass = true;
  std::vector<std::string> why;
  /// The machine's stalls within the phase's reach (definitions above): whether the
  /// witness kept every one (complete), how many, the worst and when it began, and what
  /// they account for (late ticks, overruns, late releases, delay errors). Null when the
  /// machine was not watched.
  nlohmann::ordered_json machine;
  /// The phase missed its timing targets only by what the machine's stalls account for.
  bool timing_machine_limited = false;
};

struct SoakProcessGrowth {
  std::string name;
  double rss_first_phase_kib = 0.0;
  double rss_max_after_kib = 0.0;
  double growth = 0.0;  // rss_max_after / rss_first_phase - 1
};

struct SoakResult {
  bool pass = false;
  /// Failed only on phases whose timing was machine-limited (and on nothing else).
  bool timing_machine_limited = false;
  std::vector<std::string> reasons;  // one sentence per failure
  std::vector<SoakPhaseResult> phases;
  std::vector<SoakMinute> minutes;
  std::vector<SoakProcessGrowth> processes;
};

/// Judges the run. False with *error (user-facing) if the log or resources.csv cannot be
/// read, or the phases are empty or not in order.
bool AnalyseSoak(const SoakInput& in, SoakResult* out, std::string* error);

/// soak.json: verdict ("pass"/"fail"), reasons[], phases[] (index, value, start_s, end_s,
/// metrics, pass, why), minutes[], processes[] (name, rss_first_phase_kib,
/// rss_max_after_kib, growth).
nlohmann::ordered_json SoakJson(const SoakResult& r);

}  // namespace shoal

// What shoal run reports: the launcher's side of the run (launcher/launcher.h) and what the
// run's log says, analysed with the code of shoal analyze (analysis/), with the verdict of
// shoal sim and shoal analyze (analysis/verdict.h).
#pragma once

#include <cstdint>
#include <cstdio>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "analysis/analysis.h"
#include "launcher/launcher.h"

namespace shoal {

struct RunReport {
  std::string scenario;
  int followers = 0;
  double control_rate_hz = 0.0;
  LaunchResult launch;
  bool log_readable = false;             // false: the log could not be opened (a problem)
  RunSummary summary;                    // from the log; all zero without Shoal data in it
  int diverged_follower = 0;             // first follower that diverged, 0 if none
  bool converged = false;                // FormationConverged (analysis/verdict.h)
  std::int64_t log_states_expected = 0;  // (final tick + 1) * (followers + 1)
  std::vector<std::string> problems;     // the launch's, and an unreadable log
  /// Every expected vehicle state is in the log (log_states >= log_states_expected);
  /// log_problems says what was lost, and how much, when not.
  bool log_complete = false;
  std::vector<std::string> log_problems;
  /// Restarted processes (launch.restarts) as the log shows them: the states each never
  /// published while it was down (real time), counted apart from what the log lost:
  /// log_complete judges the states the processes published.
  std::vector<RestartAnalysis> log_restarts;
  std::int64_t states_missing_in_restarts = 0;
  /// An interrupted run: the states missing before each vehicle's last logged one (the
  /// part that ran), less the ticks a restarted process was down for there; what the
  /// interruption cut off after them is not counted. 0 for a run that was not interrupted.
  std::int64_t states_lost_before_interruption = 0;
  /// Real time: no process overran a period, and every process's loop lateness p99 (the
  /// emulator's: release error p99) stayed within kMaxLatenessP99S; always true in
  /// lockstep, which reads no clock. timing_problems names each process that did not.
  bool timing_ok = true;
  std::vector<std::string> timing_problems;
  /// Real time: timing_ok is false, and the machine itself stalled for at least half of
  /// every overrun (the emulator's: every late release) of every process named in
  /// timing_problems (launch.machine, JudgeTiming): the run's timing is what this machine
  /// allows.
  bool timing_machine_limited = false;
  /// The log was read with the run's key: what did not authenticate (forged, another
  /// run's) was dropped before anything above counted it (docs/run.md).
  bool bus_authenticated = false;
  std::int64_t unauthenticated = 0;
  std::map<std::string, std::int64_t> unauthenticated_by_channel;
  /// Real time: the leader and vehicles whose loop lateness p99 was above
  /// kSlowLoopFraction of a period (within the verdict's limits or not).
  int slow_loops = 0;
  /// What the user can do about what went wrong, where shoal run knows a lever
  /// (StaggerHint); printed after the summary, "hints" in --json.
  std::vector<std::string> hints;
  bool all_processes_ok() const { return problems.empty() && !launch.interrupted; }
};

/// Real-time verdict: a loop lateness (or release error) p99 beyond one 50 Hz control
/// period fails the run, and so does any overrun (docs/run.md).
constexpr double kMaxLatenessP99S = 0.02;
/// A loop whose lateness p99 is above this fraction of its period is slow (RunReport::
/// slow_loops): 2 ms at 50 Hz, the loop lateness p99 shoal run is measured against at
/// scale (docs/benchmarks.md).
constexpr double kSlowLoopFraction = 0.1;

/// How a real-time run was placed, for StaggerHint.
struct LoopPlacement {
  bool staggered = false;        // the followers' loops were staggered (not --no-stagger)
  bool one_host = true;          // no --hosts: every loop on this machine
  bool stagger_allowed = false;  // the scenario's smallest delay is above one period
  long cpus = 1;                 // this machine's online CPUs
};
/// A real-time run in which several processes failed the timing verdict or were slow
/// loops, unstaggered (--no-stagger), on one machine with more loops (followers, leader,
/// channel emulator) than CPUs, in a scenario that allows staggering: says that every loop
/// woke at the start of each period and that without --no-stagger they are spread
/// (docs/run.md). Empty otherwise: staggered, over several hosts, or where the loops had a
/// CPU each, staggering is not what the run lacked; one late process is that process's
/// trouble (a stall, a fault).
std::string StaggerHint(const RunReport& r, const LoopPlacement& p);
/// The same kind of run, its loops staggered (or in a scenario that leaves no room to),
/// not every loop at SCHED_FIFO: says that as root --sched-fifo all gives each loop a CPU
/// at its instant ahead of the machine's other work (docs/run.md). Empty otherwise, and
/// where StaggerHint has something to say.
std::string FifoHint(const RunReport& r, const LoopPlacement& p);

/// Real time: judges each process's timing from its last health report in `a` (its
/// figures since it started), against kMaxLatenessP99S and no overrun; sets timing_ok,
/// timing_problems, slow_loops and timing_machine_limited. The problem of the leader or a
/// vehicle whose every overrun, as it noted them in its output file
/// (runtime/overrun_note.h), the machine itself accounts for (r->launch.machine: a stall
/// covering at least half the time the tick lost) says so; so does the channel
/// emulator's when the machine accounts for every late release it noted. At 50 Hz, where
/// the limit is a period, a loop cannot be late beyond it without overrunning, so its
/// lateness p99 beyond the limit is then the machine's too; at lower rates such a problem
/// is not put on the machine. A restarted process's and a process's on another kernel
/// (launch.unwatched_ids) never are.
void JudgeTiming(const RunAnalysis& a, double period_s, RunReport* r);

/// Reads the run's log (launch.log) and builds the report.
RunReport MakeRunReport(const Scenario& s, LaunchResult launch);

/// The report as shoal run --json prints it (docs/run.md).
nlohmann::ordered_json RunReportJson(const RunReport& r);
/// The readable summary.
void PrintRunReport(const RunReport& r, std::FILE* out);
/// 130 interrupted; 1 a process failed, the log is unreadable or incomplete, a real-time
/// process overran or was late, or the formation did not converge or diverged; else 0
/// (docs/cli.md).
int RunExitStatus(const RunReport& r);

}  // namespace shoal

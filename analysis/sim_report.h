// shoal sim as a library: runs a scenario's whole swarm in one process (core/swarm.h),
// optionally writes the run as an LCM log on the SIL channels, and reports the outcome.
// The command (tools/sim_command.cc) only parses flags and prints the report.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/metrics.h"
#include "core/scenario.h"

namespace shoal {

struct SimRunOptions {
  std::string out;         // LCM log path; "" = no log
  double duration_s = -1;  // simulated seconds; < 0: the scenario's
  bool show_progress = false;  // a progress line on stderr
  /// Polled every tick; the run stops (interrupted) once it returns true. May be null.
  bool (*stop_requested)() = nullptr;
};

struct SimFollowerReport {
  int id = 0;
  FormationErrors final_errors;
  double saturation_fraction = 0.0;
  std::int64_t neighbour_timeouts = 0;
  std::int64_t msgs_received = 0;
};

struct SimReport {
  std::string scenario;
  int followers = 0;
  double control_rate_hz = 0.0;
  std::uint64_t seed = 0;
  double position_tol_m = 0.0, velocity_tol_mps = 0.0;
  bool converged = false;  // FormationConverged (analysis/verdict.h)
  double convergence_time_s = -1.0;
  FormationErrors final_worst;
  double max_position_error_m = 0.0;
  double sim_time_s = 0.0, wall_time_s = 0.0;
  std::int64_t ticks = 0, delivered = 0, dropped = 0;
  bool interrupted = false;
  int diverged_follower = 0;
  std::vector<SimFollowerReport> per_follower;
  std::string log;  // "" = no log written
  std::int64_t log_events = 0;
  /// The log could not be written (full disk, I/O error): why, and what it holds. The run
  /// stopped at that tick; "" if the log (if any) was written whole.
  std::string log_error;
};

/// Runs scenario `s`. Returns false with *error (and runs nothing) if the log cannot be
/// opened or its first event cannot be written, or the run does not fit in memory. A
/// write failure during the run stops it and is reported in report->log_error.
bool RunSimulation(const Scenario& s, const SimRunOptions& opt, SimReport* report,
                   std::string* error);

/// The report as shoal sim --json prints it (docs/sim.md).
nlohmann::ordered_json SimReportJson(const SimReport& r);
/// The readable summary.
void PrintSimReport(const SimReport& r, std::FILE* out);
/// 0 converged, 1 not converged or diverged or the log could not be written whole, 130
/// interrupted (analysis/verdict.h).
int SimExitStatus(const SimReport& r);

}  // namespace shoal

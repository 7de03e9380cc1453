// shoal analyze --json: the analysis of a run as one JSON object (keys in docs/analyze.md).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "analysis/analysis.h"
#include "analysis/run_data.h"

namespace shoal {

/// Where the run came from: a log file, or (live) the LCM URL in RunData::source.
struct AnalysisSource {
  bool live = false;
  std::string log;  // the log's path (not live)
};

/// The formation outcome every command's JSON reports under the same keys, in this order
/// (shoal sim, shoal run, shoal analyze): converged, convergence_time_s and the worst
/// follower's final errors. Unknown values (no formation, not converged) are null.
void AddFormationKeys(bool converged, double convergence_time_s,
                      const FormationErrors& final_worst, nlohmann::ordered_json* j);
/// sim_time_s, wall_time_s and realtime_factor (null without a wall time).
void AddTimingKeys(double sim_time_s, double wall_time_s, nlohmann::ordered_json* j);

nlohmann::ordered_json AnalysisJson(const RunData& run, const RunAnalysis& a,
                                    const AnalysisSource& source);

}  // namespace shoal

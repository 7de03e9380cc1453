// Tidy CSV export of a run (docs/analyze.md documents every column): one file per vehicle,
// the channel decisions, the health reports. Header row, no comments, plain numbers
// (NaN where a value does not exist), so pandas.read_csv and MATLAB readtable load them
// directly. Numbers are written in their shortest exact form (std::to_chars).
#pragma once

#include <string>
#include <vector>

#include "analysis/analysis.h"
#include "analysis/run_data.h"

namespace shoal {

/// Writes into `dir` (created if missing): vehicle_<id>.csv for every vehicle with states,
/// channel_events.csv, health.csv. States and channel events at impossible times
/// (a.bounds, ChannelEventTimeOf) are left out, as the analysis leaves them out. False with *error (user-facing) if the directory or a
/// file cannot be written. *files receives the paths written.
bool WriteRunCsv(const RunData& run, const RunAnalysis& a, const std::string& dir,
                 std::vector<std::string>* files, std::string* error);

}  // namespace shoal

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

nlohmann::ordered_json AnalysisJson(const RunData& run, const RunAnalysis& a,
                                    const AnalysisSource& source);

}  // namespace shoal

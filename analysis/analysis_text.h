// shoal analyze's readable report of a run.
#pragma once

#include <cstdio>

#include "analysis/analysis.h"
#include "analysis/analysis_json.h"
#include "analysis/run_data.h"

namespace shoal {

/// The summary shoal analyze prints without --json: the run, the formation verdict and
/// errors per follower, the channel's ground truth and each process's health.
void PrintAnalysisText(std::FILE* out, const RunData& run, const RunAnalysis& a,
                       const AnalysisSource& source);

}  // namespace shoal

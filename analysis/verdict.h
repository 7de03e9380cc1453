// The verdict of a run and the exit status that carries it, shared by shoal sim, shoal run
// and shoal analyze so that the three agree on the same run (docs/cli.md).
#pragma once

#include "analysis/analysis.h"

namespace shoal {

/// Exit statuses of the shoal commands (the table is in docs/cli.md).
enum ExitStatus : int {
  kExitOk = 0,             // ran, and the verdict is success
  kExitFailed = 1,         // ran, and the verdict is failure (not converged, diverged, ...)
  kExitBadInput = 2,       // nothing was run: bad options, scenario or input file
  kExitIncomplete = 3,     // shoal analyze --live: the stream missed part of the run
  kExitInterrupted = 130,  // stopped by SIGINT/SIGTERM (128 + SIGINT, as shells report it)
};

/// Converged: every follower stayed within the scenario's tolerances from some time to the
/// end of the run (FormationMetrics::converged), and no follower diverged (non-finite
/// state or |pitch| > 80 deg; `diverged_follower` is its id, 0 for none).
inline bool FormationConverged(bool within_tolerance_to_end, int diverged_follower) {
  return within_tolerance_to_end && diverged_follower == 0;
}

/// The same verdict from a run's log: false without a formation (no scenario or no
/// leader states), since then nothing says the formation converged.
inline bool FormationConverged(const RunAnalysis& a) {
  return a.has_formation && FormationConverged(a.summary.converged, a.diverged_follower);
}

}  // namespace shoal

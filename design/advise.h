// Gains to advise for a scenario (`shoal design --advise`): along the scenario's own gain
// shape, the gains (c^2 k1, c k2) that Theorem 3 certifies at the delay bound h, or, when
// no scale does, the scale whose gains Theorem 3 certifies for the largest delay.
//
// Why the scale family: k1 -> c^2 k1, k2 -> c k2 keeps the shape k1 / k2^2 and divides the
// exact delay margin by c (docs/theory.md, "Scaling law"); it is the family of the
// verdict's advice and of the tuner's constraint. Why Theorem 3 and not the exact margin
// as the criterion: the exact margin grows without bound as c -> 0, while an uncertain
// factor needs enough velocity gain (k2 lambda_min(H) > sqrt(2 lambda_max(J^2)),
// docs/theory_theorem3.md), so only Theorem 3 weighs both.
#pragma once

#include <string>
#include <vector>

#include "core/theory.h"
#include "design/theorem3.h"

namespace shoal {
namespace design {

struct AdviceOptions {
  /// Scales tried: c = 2^(j / steps_per_doubling) for c in [c_min, c_max], nearest to
  /// c = 1 (the scenario's gains) first.
  double c_min = 0.125;
  double c_max = 4.0;
  int steps_per_doubling = 4;
  /// Golden-section steps over log c when no scale certifies h (each a MaxDelayTheorem3).
  int golden_steps = 6;
  double max_delay_tol_s = 2e-3;  ///< resolution of every max_delay_s
};

struct AdviceInput {
  /// H, the scenario's k1, k2, the delay bound h and kappa, the Lipschitz data.
  Theorem3Input theorem3;
  std::vector<theory::Complex> eigenvalues;  ///< of H
  theory::Lipschitz lipschitz;
  bool factor_slopes_known = false;  ///< report the margin with the factor linearised
};

struct GainAdvice {
  double scale = 1.0;  ///< c: the advised gains are (c^2 k1, c k2)
  double k1 = 0.0, k2 = 0.0;
  /// Theorem 3 (corrected LMI) certifies the advised gains at the input's h and kappa.
  bool certified_at_h = false;
  /// Largest h Theorem 3 certifies for them (0: none, not even h = 0).
  double theorem3_max_delay_s = 0.0;
  bool found = false;  ///< some scale is certified at least at h = 0
  double delay_margin_s = 0.0;  ///< exact constant-delay margin of the advised gains
  /// The same with the uncertain factor linearised (negative: not available).
  double delay_margin_with_factor_s = -1.0;
  /// Theorem 3 at h for the advised gains if certified there, else at max_delay_s.
  Theorem3Result certificate;
  std::string how;  ///< one sentence: how the gains were chosen
  int solves = 0;   ///< CSDP solves spent
  double seconds = 0.0;
};

/// Precondition: theorem3.IsValid() (Theorem 3 applies: kappa < 1, Lipschitz data known).
GainAdvice AdviseGains(const AdviceInput& in, const AdviceOptions& options = {});

/// Writes the scenario file `scenario_path` to `out_path` with [control] k1 and k2 replaced
/// and [run] name suffixed with "_advised" (TOML re-serialised by toml++: comments are
/// dropped); the result is re-read with the scenario loader before it counts as written.
bool WriteScenarioWithGains(const std::string& scenario_path, double k1, double k2,
                            const std::string& out_path, std::string* err);

}  // namespace design
}  // namespace shoal

// The verdict of `shoal design`: are the gains certified for the scenario's delays, by
// which result, with what margin, and what to change if not. Pure logic over the numbers
// of core/theory (and, when it is wired in, Theorem 3's LMI).
#pragma once

#include <optional>
#include <string>

#include "core/theory.h"

namespace shoal {
namespace design {

/// What the uncertain factor is, as far as the theorems are concerned.
enum class FactorKind {
  kNone,       ///< no uncertain factor
  kLipschitz,  ///< F_i = f(x_i) - f(x_0), Lipschitz with rho0 (Theorems 2 and 3 apply)
  kUncovered,  ///< present but not of that form (ocean current, absolute F~)
};

struct VerdictInput {
  double k1 = 0.0, k2 = 0.0;
  double h_s = 0.0;
  /// The control period: a message is used at the first tick after it arrives, so in a
  /// run a delay h acts as up to ceil(h / period) periods, and never less than one.
  double period_s = 0.0;
  std::optional<double> kappa;  ///< empty: tau(t) has no bounded derivative
  /// Why kappa is empty ("uniform jitter draws a new delay per message", "a channel event
  /// makes tau jump up, ..."); "" if unknown.
  std::string kappa_unbounded_why;
  bool delay_time_varying = false;
  /// Every link (and the uncertain factor) has one and the same constant delay (or none).
  bool delay_common_constant = true;
  FactorKind factor = FactorKind::kNone;
  double rho0 = 0.0;
  const theory::Theorem1* theorem1 = nullptr;  ///< null if W does not exist
  const theory::Theorem2* theorem2 = nullptr;  ///< null if not evaluated (no rho0)
  const theory::DelayMargin* margin = nullptr;
  /// The margin with the uncertain factor linearised (an indication); may be null.
  const theory::FactorDelayMargin* factor_margin = nullptr;
  double safety = 2.0;  ///< for the "what to change" advice
  /// Theorem 3 (LMI (27)-(28)) at the scenario's h and kappa: true = feasible (certified),
  /// false = infeasible or solver failure, empty = not evaluated.
  std::optional<bool> theorem3_certified;
  /// Theorem 3's largest certified h (0: infeasible even at h = 0), if evaluated.
  std::optional<double> theorem3_max_delay_s;
};

struct Verdict {
  bool certified = false;
  std::string by;      ///< the result that certifies (empty if none)
  std::string reason;  ///< one sentence: what holds and what does not
  std::string advice;  ///< what to change (empty when certified without caveat)
  /// exact constant-delay margin / h (infinite when h = 0).
  double margin_over_h = 0.0;
  std::string Line() const;  ///< "verdict: CERTIFIED ..." / "verdict: NOT CERTIFIED ..."
};

Verdict Decide(const VerdictInput& in);

}  // namespace design
}  // namespace shoal

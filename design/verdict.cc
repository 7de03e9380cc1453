#include "design/verdict.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "design/format.h"

namespace shoal {
namespace design {
namespace {

std::string Lambda(const theory::Complex& l) {
  if (std::abs(l.imag()) < 1e-12) return G4(l.real());
  return G4(l.real()) + (l.imag() < 0 ? " - " : " + ") + G4(std::abs(l.imag())) + "j";
}

/// k1 -> c^2 k1, k2 -> c k2 divides the margin by c: the gains that give `target_s`.
std::string ScaleAdvice(const VerdictInput& in, double target_s) {
  const double c = in.margin->tau_s / target_s;
  return "scale the gains to k1 = " + G4(c * c * in.k1) + ", k2 = " + G4(c * in.k2) +
         " (k1 x c^2, k2 x c with c = " + G4(c) + "), which makes the exact margin " +
         G4(target_s) + " s = " + G4(in.safety) + " x h, at the price of a response " +
         G4(1.0 / c) + " x slower; or run --tune";
}

const char* kComponent[] = {"x", "y", "z", "theta", "psi"};

bool FactorUnstable(const VerdictInput& in) {
  return in.factor_margin && in.factor_margin->available && !in.factor_margin->stable_at_zero;
}

std::string MarginText(const VerdictInput& in) {
  const theory::DelayMargin& m = *in.margin;
  std::string s = "exact constant-delay margin " + G4(m.tau_s) + " s";
  if (in.h_s > 0.0) s += " = " + G4(m.tau_s / in.h_s) + " x h";
  const theory::FactorDelayMargin* f = in.factor_margin;
  if (f && f->available && in.factor != FactorKind::kNone) {
    s += f->stable_at_zero ? " (" + G4(f->tau_s) + " s with the uncertain factor linearised)"
                           : " (UNSTABLE with the uncertain factor linearised)";
  }
  return s;
}

/// Advice when the linearised factor removes all damping of a component.
std::string FactorAdvice(const VerdictInput& in) {
  const theory::FactorDelayMargin& f = *in.factor_margin;
  const std::string c = kComponent[std::max(0, f.component)];
  std::string s = "raise k2: the uncertain factor's slope " + G4(f.v_slope) + " on " + c +
                  "' exceeds the damping lambda k2 of eigenvalue " + Lambda(f.lambda);
  if (std::abs(f.lambda.imag()) < 1e-12 && f.lambda.real() > 0.0) {
    s += " (k2 > " + G4(f.v_slope / f.lambda.real()) + " is needed without delay)";
  }
  return s;
}

}  // namespace

std::string Verdict::Line() const {
  std::string s = certified ? "verdict: CERTIFIED by " + by + ": " + reason
                            : "verdict: NOT CERTIFIED: " + reason;
  if (!advice.empty()) s += (certified ? "; advice: " : "; to change: ") + advice;
  return s;
}

namespace {

/// Rule 1: some s^2 + lambda (k2 s + k1) is not Hurwitz.
Verdict UnstableWithoutDelay(const VerdictInput& in) {
  Verdict v;
  std::string which;
  for (const theory::EigenMargin& e : in.margin->per_eigenvalue) {
    if (!e.stable_at_zero) {
      which = Lambda(e.lambda);
      break;
    }
  }
  v.reason = "the loop is unstable even without delay (eigenvalue " + which +
             " of H: s^2 + lambda (k2 s + k1) has a root with Re s > 0)";
  v.advice = "raise k2 relative to k1 (a larger k2^2 / k1 damps the complex eigenvalues)";
  return v;
}

/// Rule 2, no factor: Theorem 1, or else the exact characteristic equation at tau = 0.
Verdict NoDelayNoFactor(const VerdictInput& in) {
  Verdict v;
  v.certified = true;
  if (in.theorem1 && in.theorem1->certifies) {
    v.by = "Theorem 1";
    v.reason =
        "no delay, no uncertain factor; P = Q(A+B) + (A+B)^T Q has largest "
        "eigenvalue " +
        G4(in.theorem1->P_max_eigenvalue) + " < 0";
  } else {
    v.by = "the exact characteristic equation at tau = 0";
    v.reason =
        "no delay, no uncertain factor; every s^2 + lambda (k2 s + k1) is "
        "Hurwitz (Theorem 1's Lyapunov function does not certify these gains, "
        "but it is only sufficient)";
  }
  return v;
}

/// Rule 2, Lipschitz factor: Theorem 3 at h = 0, or Theorem 2's corrected P~ test.
Verdict NoDelayLipschitzFactor(const VerdictInput& in) {
  Verdict v;
  if (in.theorem3_certified.value_or(false) && in.kappa && *in.kappa < 1.0) {
    v.certified = true;
    v.by = "Theorem 3 (LMI (27)-(28))";
    v.reason = "no delay (h = 0), uncertain factor with rho0 = " + G4(in.rho0) +
               "; the LMI is feasible";
    return v;
  }
  if (in.theorem2 && in.theorem2->certifies) {
    v.certified = true;
    v.by = "Theorem 2 (corrected)";
    v.reason = "no delay; P~ with rho0 = " + G4(in.rho0) + " has largest eigenvalue " +
               G4(in.theorem2->P_tilde_max_eigenvalue) + " < 0";
    return v;
  }
  v.reason = "no delay, but Theorem 2 does not certify the gains with rho0 = " + G4(in.rho0) +
             (in.theorem2 ? " (corrected P~ has largest eigenvalue " +
                                G4(in.theorem2->P_tilde_max_eigenvalue) + " >= 0)"
                          : "") +
             "; without the uncertain factor the loop is stable (exact)";
  if (FactorUnstable(in)) {
    v.reason += "; with the factor linearised the loop is unstable";
    v.advice = FactorAdvice(in);
  } else if (in.theorem2 && in.theorem2->k1_min_corrected) {
    v.advice = "raise k1 above " + G4(*in.theorem2->k1_min_corrected) + " and k2 above " +
               G4(*in.theorem2->k2_min_corrected) + " (corrected (20)-(21))";
  } else {
    v.advice =
        "Theorem 2's bounds (20)-(21) have no solution for this topology, alpha "
        "and beta (alpha beta <= 2 lambda_max(M^T M)); try other --alpha/--beta "
        "or higher gains checked by the P~ test";
  }
  return v;
}

/// Rule 2: h = 0.
Verdict NoDelay(const VerdictInput& in) {
  switch (in.factor) {
    case FactorKind::kNone:
      return NoDelayNoFactor(in);
    case FactorKind::kLipschitz:
      return NoDelayLipschitzFactor(in);
    case FactorKind::kUncovered:
      break;
  }
  Verdict v;
  v.reason =
      "no delay and the nominal loop is stable (exact), but the uncertain factor "
      "is not a Lipschitz f(x_i) - f(x_0): no theorem here covers it (expect a "
      "bounded formation error rather than convergence)";
  return v;
}

/// Rule 3: one common constant delay, no factor: the exact margin decides.
Verdict CommonConstantDelay(const VerdictInput& in) {
  Verdict v;
  const theory::DelayMargin& m = *in.margin;
  if (m.tau_s > in.h_s) {
    v.certified = true;
    v.by = "the exact delay margin";
    v.reason = "one constant delay h = " + G4(in.h_s) +
               " s on every link, no uncertain "
               "factor; " +
               MarginText(in);
    if (m.tau_s < in.safety * in.h_s) {
      v.advice = "the margin is below the safety factor " + G4(in.safety) + ": " +
                 ScaleAdvice(in, in.safety * in.h_s);
    }
    return v;
  }
  v.reason = "one constant delay h = " + G4(in.h_s) + " s on every link exceeds the " +
             MarginText(in) + ": the loop is unstable at this delay";
  v.advice = ScaleAdvice(in, in.safety * in.h_s);
  return v;
}

bool Theorem3Applicable(const VerdictInput& in) {
  return in.factor != FactorKind::kUncovered && in.kappa && *in.kappa < 1.0;
}

/// Rule 4: Theorem 3's LMI is feasible at (h, kappa).
Verdict ByTheorem3(const VerdictInput& in) {
  Verdict v;
  v.certified = true;
  v.by = "Theorem 3 (LMI (27)-(28))";
  v.reason =
      "tau(t) <= h = " + G4(in.h_s) + " s, d tau/dt <= kappa = " + G4(*in.kappa) +
      (in.factor == FactorKind::kLipschitz ? ", uncertain factor with rho0 = " + G4(in.rho0)
                                           : std::string(", no uncertain factor")) +
      "; " + MarginText(in);
  return v;
}

/// Rule 5, the reason: what only Theorem 3 covers, and what Theorem 3 said.
std::string OnlyTheorem3Reason(const VerdictInput& in) {
  std::string why;
  auto add = [&why](const std::string& s) { why += (why.empty() ? "" : ", ") + s; };
  if (in.delay_time_varying)
    add("the delay is time-varying (a constant-delay margin does not "
        "certify time-varying delays)");
  else if (!in.delay_common_constant)
    add("the links have different delays");
  if (in.factor == FactorKind::kLipschitz)
    add("an uncertain factor acts (rho0 = " + G4(in.rho0) + ")");
  if (in.factor == FactorKind::kUncovered)
    add("an uncertain factor acts that no theorem "
        "here covers");
  std::string t3;
  if (!Theorem3Applicable(in)) {
    t3 = in.kappa ? (in.factor == FactorKind::kUncovered
                         ? "Theorem 3 does not cover this uncertain factor"
                         : "Theorem 3 needs kappa < 1")
                  : in.kappa_unbounded_why.empty()
                        ? "Theorem 3 needs a bounded d tau/dt (kappa), which this delay model lacks"
                        : "Theorem 3 needs a bounded d tau/dt (kappa), and here " +
                              in.kappa_unbounded_why;
  } else if (!in.theorem3_certified) {
    t3 = "Theorem 3 not evaluated";
  } else {
    t3 = "Theorem 3's LMI is not feasible at h = " + G4(in.h_s) + " s";
  }
  return why + "; " + t3 + "; " + MarginText(in) + ": indications, not certificates";
}

/// Rule 5, the advice.
std::string OnlyTheorem3Advice(const VerdictInput& in) {
  if (FactorUnstable(in)) return FactorAdvice(in);
  if (in.margin->tau_s <= in.h_s) {
    return "the gains are unstable already for a constant delay h: " +
           ScaleAdvice(in, in.safety * in.h_s);
  }
  if (!Theorem3Applicable(in) || !in.theorem3_certified.has_value()) return "";
  if (in.theorem3_max_delay_s && *in.theorem3_max_delay_s <= 0.0) {
    if (in.factor == FactorKind::kNone) {
      // Without a factor the LMI is feasible at h = 0 for any kappa < 1 in exact
      // arithmetic: an "infeasible" there is the solver's margin, not the gains'.
      return "Theorem 3's LMI was not solved feasible even at h = 0, though without an uncertain "
             "factor it is feasible there for any kappa < 1: the solver's numerical margin, "
             "not the gains (a kappa near 1 makes the LMI ill-conditioned); "
             "a smaller --kappa, or the exact delay margin above, says more";
    }
    return "Theorem 3's LMI is infeasible even at h = 0 with these gains and this uncertain "
           "factor: the velocity gain must dominate the factor's slope (a necessary condition "
           "is k2 lambda_min(H) > sqrt(2 lambda_max(J^2)), docs/theory_theorem3.md); raise k2 "
           "(check the delay margin again), or weaken the factor";
  }
  return "reduce the delay below Theorem 3's max_delay_s" +
         (in.theorem3_max_delay_s ? " = " + G4(*in.theorem3_max_delay_s) + " s" : "") +
         ", or change the gains and compare max_delay_s (the LMI is only sufficient)";
}

}  // namespace

Verdict Decide(const VerdictInput& in) {
  const theory::DelayMargin& m = *in.margin;
  const double margin_over_h =
      in.h_s > 0.0 ? m.tau_s / in.h_s : std::numeric_limits<double>::infinity();
  Verdict v;
  if (!m.stable_at_zero) {
    v = UnstableWithoutDelay(in);
  } else if (in.h_s <= 0.0) {
    v = NoDelay(in);
  } else if (in.factor == FactorKind::kNone && in.delay_common_constant) {
    v = CommonConstantDelay(in);
  } else if (in.theorem3_certified.value_or(false) && Theorem3Applicable(in)) {
    // Time-varying delays or an uncertain factor: Theorem 3 (the exact margin is
    // necessary and sufficient for one constant delay, so it decides that case first).
    v = ByTheorem3(in);
  } else {
    v.reason = OnlyTheorem3Reason(in);
    v.advice = OnlyTheorem3Advice(in);
  }
  v.margin_over_h = margin_over_h;
  // The theorems are about the paper's continuous-time loop; Shoal's loop uses each state
  // at the first control tick after it arrives. A margin the run's ticks use up is no
  // certificate for the run.
  if (v.certified && in.period_s > 0.0) {
    const double ticks = std::max(1.0, std::ceil(in.h_s / in.period_s - 1e-9));
    const double acts_as = ticks * in.period_s;
    if (m.tau_s <= acts_as) {
      const double c = m.tau_s / (in.safety * acts_as);
      v.certified = false;
      v.reason = v.by + " holds for the continuous-time loop, but in a run each state is used "
                 "at the first control tick after it arrives, so the delay acts as up to " +
                 G4(acts_as) + " s (" + G4(ticks) + " control period(s) of " + G4(in.period_s) +
                 " s), and the exact constant-delay margin " + G4(m.tau_s) + " s is not above it";
      v.by.clear();
      v.advice = "scale the gains to k1 = " + G4(c * c * in.k1) + ", k2 = " + G4(c * in.k2) +
                 " (k1 x c^2, k2 x c with c = " + G4(c) + "), which makes the exact margin " +
                 G4(in.safety * acts_as) + " s = " + G4(in.safety) + " x that delay; or run --tune";
    }
  }
  return v;
}

}  // namespace design
}  // namespace shoal

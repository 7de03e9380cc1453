// The readable rendering of a DesignReport (one section per result, the verdict last).
#include <cmath>
#include <cstdio>
#include <sstream>

#include "design/report.h"
#include "design/format.h"

namespace shoal {
namespace design {
namespace {

using theory::Complex;

std::string ComplexText(const Complex& c) {
  if (std::abs(c.imag()) < 1e-12) return Fmt("%.5g", c.real());
  return Fmt("%.5g", c.real()) + (c.imag() < 0 ? " - " : " + ") + Fmt("%.5g", std::abs(c.imag())) +
         "j";
}
std::string ComplexListText(const std::vector<Complex>& v) {
  std::string s;
  for (std::size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + ComplexText(v[i]);
  return s;
}
std::string OrNone(const std::optional<double>& v) { return v ? G4(*v) : "none"; }

const char* kComponent[] = {"x", "y", "z", "theta", "psi"};

void TopologyText(const DesignReport& r, std::ostream& txt) {
  txt << "shoal design: " << r.scenario_name << " (" << r.followers << " followers; k1 = "
      << G4(r.k1) << ", k2 = " << G4(r.k2) << "; alpha = " << G4(r.alpha) << ", beta = " << G4(r.beta)
      << ")\n";
  txt << "topology\n  H eigenvalues: " << ComplexListText(r.eigenvalues) << "\n";
  if (r.unreachable_followers.empty()) {
    txt << "  Assumption 1: holds (every follower has a directed path from the leader)\n";
  } else {
    txt << "  Assumption 1: FAILS: unreachable followers";
    for (int i : r.unreachable_followers) txt << " " << i;
    txt << "\n";
  }
}

void DelayAndFactorText(const DesignReport& r, std::ostream& txt) {
  const theory::DelayBounds& d = r.delay;
  txt << "delays\n  "
      << (r.delay_from_flags ? std::string("from the flags")
                             : std::string("model ") + DelayKindName(r.delay_model))
      << (!r.per_link_overrides || r.delay_from_flags ? ""
                                                      : " (with per-link overrides: max over links)")
      << ": h = " << G4(d.h_s) << " s, kappa = "
      << (d.kappa                                ? G4(*d.kappa)
          : !r.delay_rate_unbounded_why.empty() ? "unbounded (" + r.delay_rate_unbounded_why + ")"
          : r.delay_model == DelayKind::kAcoustic || r.delay_model == DelayKind::kTrace
              ? std::string("unbounded (tau follows the range or the trace; Assumption 3 is "
                            "not guaranteed)")
              : std::string("unbounded (a new random delay per message: tau jumps)"))
      << (d.time_varying ? " (time-varying)"
          : d.constant   ? " (one constant delay)"
                         : " (different constant delays)")
      << "\n";
  txt << "uncertain factor\n  " << DisturbanceName(r.disturbance);
  if (r.disturbance != DisturbanceKind::kOceanCurrent) {
    txt << ": lambda_max(G^2) = " << G4(r.lipschitz.lambda_max_G2)
        << ", lambda_max(J^2) = " << G4(r.lipschitz.lambda_max_J2);
  }
  txt << ", rho0 = " << OrNone(r.rho0) << (r.rho0_from_flag ? " (--rho0)" : "") << "\n  "
      << r.lipschitz.note << "\n";
}

void Theorem1Text(const DesignReport& r, std::ostream& txt) {
  if (!r.theorem1) {
    txt << "theorem 1: not applicable (an eigenvalue of H has real part <= 0: no W)\n";
    return;
  }
  const theory::Theorem1& t1 = *r.theorem1;
  txt << "theorem 1 (no delay, no uncertain factor)\n  W (W H + H^T W = I):\n";
  for (Eigen::Index i = 0; i < t1.W.rows(); ++i) {
    txt << "   ";
    for (Eigen::Index k = 0; k < t1.W.cols(); ++k) txt << Fmt(" %8.4f", t1.W(i, k));
    txt << "\n";
  }
  txt << "  W eigenvalues: ";
  for (Eigen::Index i = 0; i < t1.W_eigenvalues.size(); ++i) {
    txt << (i ? ", " : "") << Fmt("%.4f", t1.W_eigenvalues(i));
  }
  txt << "\n  M^2 eigenvalues: " << ComplexListText(t1.M2_eigenvalues)
      << "\n  lambda_max(W) = " << G4(t1.lambda_max_W) << ", lambda_max(M^2) = " << G4(t1.lambda_max_M2)
      << ", lambda_max(M^T M) = " << G4(t1.lambda_max_MtM) << "\n";
  auto bound = [&](const char* what, const std::optional<double>& a,
                   const std::optional<double>& b, double lm) {
    txt << "  " << what << ": ";
    if (a) {
      txt << "k1 > " << G4(*a) << ", k2 > " << G4(*b) << "\n";
    } else {
      txt << "no gains (alpha beta = " << G4(r.alpha * r.beta) << " <= " << G4(lm) << ")\n";
    }
  };
  bound("paper's (15) with lambda_max(M^2)", t1.k1_min, t1.k2_min, t1.lambda_max_M2);
  bound("corrected, lambda_max(M^T M)", t1.k1_min_corrected, t1.k2_min_corrected,
        t1.lambda_max_MtM);
  txt << "  P = Q(A+B) + (A+B)^T Q: largest eigenvalue " << G4(t1.P_max_eigenvalue)
      << (t1.certifies ? " < 0: certifies these gains (no delay, no uncertain factor)"
                       : (t1.Q_positive_definite ? " >= 0: does not certify these gains"
                                                 : "; Q is not positive definite (k1 <= "
                                                   "alpha^2): does not certify"))
      << "\n";
}

void Theorem2Text(const DesignReport& r, std::ostream& txt) {
  if (!r.theorem2) {
    txt << "theorem 2: not evaluated (no rho0 for this uncertain factor; give --rho0)\n";
    return;
  }
  const theory::Theorem2& t2 = *r.theorem2;
  const double ab = r.alpha * r.beta;
  txt << "theorem 2 (no delay, uncertain factor with rho0 = " << G4(t2.rho0) << ")\n"
      << "  paper's (20)-(21): k11 = " << G4(t2.k11) << ", k21 = " << G4(t2.k21)
      << ", k12 = " << OrNone(t2.k12) << ", k22 = " << OrNone(t2.k22);
  if (t2.k1_min) {
    txt << "  =>  k1 > " << G4(*t2.k1_min) << ", k2 > " << G4(*t2.k2_min) << "\n";
  } else {
    txt << "  =>  no gains (alpha beta - 2 lambda_max(M^2) = "
        << G4(ab - 2 * r.theorem1->lambda_max_M2) << " <= 0)\n";
  }
  txt << "  corrected (factor 2, M^T M): k11 = " << G4(t2.k11_corrected)
      << ", k21 = " << G4(t2.k21_corrected) << ", k12 = " << OrNone(t2.k12_corrected)
      << ", k22 = " << OrNone(t2.k22_corrected);
  if (t2.k1_min_corrected) {
    txt << "  =>  k1 > " << G4(*t2.k1_min_corrected) << ", k2 > " << G4(*t2.k2_min_corrected)
        << "\n";
  } else {
    txt << "  =>  no gains (alpha beta - 2 lambda_max(M^T M) = "
        << G4(ab - 2 * r.theorem1->lambda_max_MtM) << " <= 0)\n";
  }
  txt << "  P~ for these gains: largest eigenvalue " << G4(t2.P_tilde_max_eigenvalue)
      << (t2.certifies ? " < 0: certifies them (no delay)" : ": does not certify them") << "\n";
}

void Theorem3Text(const DesignReport& r, std::ostream& txt) {
  const Theorem3Section& t = r.theorem3;
  txt << "theorem 3 (LMI (27)-(28) corrected, every multiplier free, CSDP)\n";
  if (!t.evaluated) {
    txt << "  not evaluated: " << t.not_evaluated_reason << "\n";
    return;
  }
  const MaxDelayResult& maxd = t.max_delay;
  txt << "  lambda_max(G^2) = " << G4(t.input.lambda_G2) << ", lambda_max(J^2) = "
      << G4(t.input.lambda_J2) << (t.rho0_from_flag ? " (from --rho0)" : "") << "\n";
  txt << "  at h = " << G4(t.input.h_s) << " s, kappa = " << G4(t.input.kappa) << ": "
      << (t.at_h.certifies() ? "FEASIBLE (certified)" : "infeasible") << "; " << t.at_h.message
      << "\n";
  if (!maxd.input_valid) {
    txt << "  max delay: " << maxd.message << "\n";
  } else if (!maxd.feasible_at_zero) {
    txt << "  max delay: none (infeasible even at h = 0; docs/theory_theorem3.md says why)\n";
  } else {
    txt << "  max_delay_s = " << G4(maxd.max_delay_s) << " s" << (maxd.hit_cap ? " (search cap)" : "")
        << " (" << maxd.solves << " solves)\n";
  }
  const PaperMultipliersResult& p = t.paper;
  txt << "  paper's multipliers (X = 0.3I, Y = 0, Z = I, psi = 0.1I, Phi = 0.6I), best Q: "
      << (p.solved ? "lambda_max(Xi) = " + G4(p.max_eigenvalue) +
                         (p.max_eigenvalue < 0 ? " < 0 (certifies)" : " >= 0 (does not certify)")
                   : p.message)
      << "\n";
  if (!t.certificate_path.empty()) {
    const Theorem3Result& c = t.CertificateResult();
    txt << "  certificate (h = " << G4(c.input.h_s) << " s, "
        << (c.certifies() ? "feasible" : "NOT feasible: the solver's last matrices")
        << ") written to " << t.certificate_path << "\n";
  }
}

void DelayMarginText(const DesignReport& r, std::ostream& txt) {
  const theory::DelayMargin& m = r.margin;
  const double h = r.delay.h_s;
  txt << "exact delay margin (one constant delay on own and neighbour states, no uncertain "
         "factor)\n";
  if (!m.stable_at_zero) {
    txt << "  UNSTABLE without delay: margin 0\n";
    return;
  }
  const theory::EigenMargin& c = m.per_eigenvalue[m.critical];
  txt << "  delay_margin_s = " << Fmt("%.4f", m.tau_s) << " s (eigenvalue " << ComplexText(c.lambda)
      << ", crossing at " << G4(std::abs(c.omega_rad_s)) << " rad/s)";
  if (h > 0) txt << " = " << Fmt("%.2f", m.tau_s / h) << " x h";
  txt << "\n  per eigenvalue:";
  for (std::size_t i = 0; i < m.per_eigenvalue.size(); ++i) {
    const theory::EigenMargin& e = m.per_eigenvalue[i];
    txt << (i ? "; " : " ") << ComplexText(e.lambda) << ": " << Fmt("%.4f", e.tau_s) << " s";
  }
  txt << "\n";
}

void FactorMarginText(const DesignReport& r, std::ostream& txt) {
  if (!r.factor_margin_shown) return;
  const theory::FactorDelayMargin& f = r.factor_margin;
  txt << "delay margin with the uncertain factor linearised (slopes frozen at their worst "
         "corner; indication only)\n  ";
  if (!f.stable_at_zero) {
    txt << "UNSTABLE without delay: component " << kComponent[f.component] << " with slope "
        << G4(f.v_slope) << " on its rate, eigenvalue " << ComplexText(f.lambda)
        << " (lambda k2 - slope has no damping left)\n";
    return;
  }
  txt << Fmt("%.4f", f.tau_s) << " s (component " << kComponent[f.component] << ", eigenvalue "
      << ComplexText(f.lambda) << ", slopes dx " << G4(f.x_slope) << ", dv " << G4(f.v_slope) << ")";
  if (r.delay.h_s > 0) txt << " = " << Fmt("%.2f", f.tau_s / r.delay.h_s) << " x h";
  txt << "\n";
}

std::string Theorem1Cell(const TopologyResult& t) {
  if (!t.theorem1_available) return "no W";
  return (t.theorem1_certifies ? "certifies (P " : "does not (P ") + G4(t.theorem1_P_max_eigenvalue) +
         ")";
}

void CommonLyapunovText(const CommonLyapunov& c, std::ostream& txt) {
  txt << "  ";
  if (!c.attempted) {
    txt << "common Lyapunov certificate not sought: " << c.not_attempted_reason << "\n";
    return;
  }
  if (c.found()) {
    txt << "common Lyapunov certificate found (min eig of P " << G4(c.check.P_min_eigenvalue)
        << ", max eig of each A_k^T P + P A_k:";
    for (std::size_t k = 0; k < c.check.max_eigenvalues.size(); ++k) {
      txt << (k ? ", " : " ") << G4(c.check.max_eigenvalues[k]);
    }
    txt << "; eps = " << G4(c.eps) << ", CSDP " << Fmt("%.3f", c.seconds)
        << " s)\n  the delay-free error system, without uncertain factor, is stable under "
           "arbitrary switching among these topologies; with delays only the per-topology "
           "margins apply\n";
    return;
  }
  txt << "no common quadratic Lyapunov function found (CSDP status " << c.csdp_return_code << ": "
      << c.csdp_status;
  if (c.P.size() > 0 && std::isfinite(c.check.P_min_eigenvalue) && !c.check.max_eigenvalues.empty()) {
    txt << "; its P fails the check: min eig of P " << G4(c.check.P_min_eigenvalue)
        << ", max eig of each A_k^T P + P A_k:";
    for (std::size_t k = 0; k < c.check.max_eigenvalues.size(); ++k) {
      txt << (k ? ", " : " ") << G4(c.check.max_eigenvalues[k]);
    }
  }
  txt << ")\n  stability under arbitrary switching is not shown (it may still hold, e.g. "
         "with a dwell time)\n";
}

void SwitchingText(const DesignReport& r, const SwitchingSection& sw, std::ostream& txt) {
  txt << "switching topology (" << sw.topologies.size()
      << " topologies; the sections above are for topology 0, the [swarm] one)\n";
  char head[160];
  std::snprintf(head, sizeof(head), "  %-8s  %-18s%10s  %-12s  %-26s%s\n", "topology", "from",
                "at_s", "assumption 1", "theorem 1", "exact margin");
  txt << head;
  for (const TopologyResult& t : sw.topologies) {
    char row[200];
    std::snprintf(row, sizeof(row), "  %-8d  %-18s%10s  %-12s  %-26s%s\n", t.index,
                  TopologySource(t).c_str(), G4(t.at_s).c_str(),
                  t.unreachable_followers.empty() ? "holds" : "FAILS",
                  Theorem1Cell(t).c_str(),
                  t.margin.stable_at_zero ? (Fmt("%.4f", t.margin.tau_s) + " s").c_str()
                                          : "UNSTABLE (0)");
    txt << row;
  }
  const double h = r.delay.h_s;
  txt << "  smallest exact margin " << Fmt("%.4f", sw.min_margin_s) << " s (topology "
      << sw.critical << ")";
  if (h > 0) {
    txt << " = " << Fmt("%.2f", sw.min_margin_s / h) << " x h; h = " << G4(h) << " s is "
        << (h < sw.min_margin_s ? "below every topology's margin"
                                : "NOT below every topology's margin");
  }
  txt << "\n";
  CommonLyapunovText(sw.common, txt);
}

void FormationDelayText(const DesignReport& r, const FormationDelay& f, std::ostream& txt) {
  const double m = r.GoverningMarginS();
  auto judge = [&](double d) { return d < m ? std::string(": OK") : std::string(": EXCEEDS it"); };
  txt << "acoustic delays in formation (offsets_m; " << f.acoustic_links << " acoustic links"
      << (r.switching ? " of every topology" : "") << ")\n";
  txt << "  in formation the delay is at most " << Fmt("%.4f", f.in_formation_s) << " s (link "
      << f.from << " -> " << f.to << ", " << G4(f.range_m) << " m) (margin " << Fmt("%.4f", m)
      << " s)" << judge(f.in_formation_s) << "\n";
  txt << "  worst case (at max_range_m) " << Fmt("%.4f", f.model_bound_s) << " s (margin "
      << Fmt("%.4f", m) << " s)" << judge(f.model_bound_s) << "\n";
  if (f.beyond_range_links > 0) {
    txt << "  " << f.beyond_range_links
        << " link(s) longer than max_range_m in formation: their messages are lost\n";
  }
}

void EmpiricalText(const EmpiricalSection& e, std::ostream& txt) {
  const EmpiricalMargin& em = e.margin;
  txt << "empirical margin (--empirical)\n";
  if (!em.converges_without_delay) {
    txt << "  does NOT converge even with the minimum delay of one control period ("
        << G4(em.period_s) << " s)\n";
  } else if (em.capped) {
    txt << "  converges at every delay tried, up to " << G4(em.cap_s)
        << " s (the neighbour timeout limits the search)\n";
  } else {
    txt << "  empirical_margin_s = " << Fmt("%.3f", em.margin_s) << " s (converges; does not at "
        << Fmt("%.3f", em.first_failing_s) << " s; resolution one control period)\n";
  }
  txt << "  " << em.runs << " runs of " << G4(em.duration_s) << " s in " << Fmt("%.1f", e.wall_s)
      << " s wall; model: " << e.model << "\n";
}

void TunePointText(const DesignReport& r, const char* name, const TunePoint& p,
                   double factor_margin_s, std::ostream& txt) {
  txt << "  " << name << ": k1 = " << G4(p.k1) << ", k2 = " << G4(p.k2) << ", margin "
      << Fmt("%.4f", p.margin_s) << " s";
  if (r.factor_margin_shown) {
    txt << " (with the factor linearised: " << Fmt("%.4f", factor_margin_s) << " s)";
  }
  txt << ", cost " << G4(p.cost) << " (position ISE " << G4(p.position_ise_m2s) << " m^2 s), "
      << (p.converged ? "converged at " + Fmt("%.2f", p.convergence_time_s) + " s"
                      : std::string("did NOT converge"))
      << "\n";
}

std::string TuneIntegrand(const DesignReport& r, CostKind cost) {
  const std::string pt = "(e_p/" + G4(r.position_tol_m) + " m)^2";
  const std::string vt = "(e_v/" + G4(r.velocity_tol_mps) + " m/s)^2";
  if (cost == CostKind::kPositionIse) return "e_p^2 dt";
  if (cost == CostKind::kIse) return pt + " + " + vt + " dt";
  return "t (" + pt + " + " + vt + ") dt";
}

void TuneText(const DesignReport& r, const TuneSection& t, std::ostream& txt) {
  const TuneResult& tr = t.result;
  txt << "tune (--tune, cost " << CostName(t.cost) << ": integral of " << TuneIntegrand(r, t.cost)
      << " over " << G4(tr.horizon_s) << " s, summed over followers; margin >= " << G4(r.safety)
      << " x max(h, control period) = " << G4(tr.required_margin_s) << " s)\n";
  TunePointText(r, "before", tr.before, t.before_factor_margin_s, txt);
  if (!tr.before_feasible) txt << "          (the scenario's gains do not meet the margin requirement)\n";
  if (tr.ok) {
    TunePointText(r, "after ", tr.after, t.after_factor_margin_s, txt);
  } else {
    txt << "  FAILED: " << tr.message << "\n";
  }
  txt << "  starts:";
  for (const TuneStart& st : tr.starts) {
    txt << " (" << G4(st.k1_start) << ", " << G4(st.k2_start) << ") -> ";
    if (st.usable) {
      txt << "(" << G4(st.k1) << ", " << G4(st.k2) << ") cost " << G4(st.cost) << ";";
    } else {
      txt << "not usable (" << st.message << ");";
    }
  }
  txt << "\n  " << tr.sim_runs << " simulations in " << Fmt("%.1f", t.wall_s) << " s wall"
      << " (convergence times from full " << G4(r.duration_s) << " s runs)\n";
}

void AdviceText(const DesignReport& r, const AdviceSection& a, std::ostream& txt) {
  txt << "advised gains (--advise)\n";
  if (!a.evaluated) {
    txt << "  not evaluated: " << a.not_evaluated_reason << "\n";
    return;
  }
  const GainAdvice& g = a.advice;
  txt << "  k1 = " << G4(g.k1) << ", k2 = " << G4(g.k2) << ": " << g.how << "\n  ";
  if (g.certified_at_h) {
    txt << "CERTIFIED by Theorem 3 at h = " << G4(r.delay.h_s) << " s, kappa = "
        << G4(r.theorem3.input.kappa) << "; it certifies up to max_delay_s = "
        << G4(g.theorem3_max_delay_s) << " s\n";
  } else if (g.found) {
    txt << "NOT certified at h = " << G4(r.delay.h_s) << " s: Theorem 3 certifies up to "
        << "max_delay_s = " << G4(g.theorem3_max_delay_s) << " s (the LMI is only sufficient)\n";
  } else {
    txt << "NOT certified: Theorem 3 certifies no delay for them\n";
  }
  txt << "  exact delay margin " << Fmt("%.4f", g.delay_margin_s) << " s";
  if (r.delay.h_s > 0) txt << " = " << Fmt("%.2f", g.delay_margin_s / r.delay.h_s) << " x h";
  if (g.delay_margin_with_factor_s >= 0.0) {
    txt << " (" << Fmt("%.4f", g.delay_margin_with_factor_s) << " s with the factor linearised)";
  }
  txt << "; " << g.solves << " CSDP solves in " << Fmt("%.1f", g.seconds) << " s\n";
  if (!a.scenario_written.empty()) {
    txt << "  scenario with these gains written to " << a.scenario_written << "\n";
  }
}

}  // namespace

std::string DesignReportText(const DesignReport& r) {
  std::ostringstream txt;
  TopologyText(r, txt);
  DelayAndFactorText(r, txt);
  Theorem1Text(r, txt);
  Theorem2Text(r, txt);
  Theorem3Text(r, txt);
  DelayMarginText(r, txt);
  FactorMarginText(r, txt);
  if (r.switching) SwitchingText(r, *r.switching, txt);
  if (r.formation_delay) FormationDelayText(r, *r.formation_delay, txt);
  if (r.empirical) EmpiricalText(*r.empirical, txt);
  if (r.tune) TuneText(r, *r.tune, txt);
  txt << r.verdict.Line() << "\n";
  if (r.advice) AdviceText(r, *r.advice, txt);
  return txt.str();
}

}  // namespace design
}  // namespace shoal

#include "tools/design_command.h"

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <cerrno>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "core/theory.h"
#include "core/topology.h"
#include "design/empirical_margin.h"
#include "design/theorem3.h"
#include "design/tune.h"
#include "design/verdict.h"
#include "scenario/loader.h"
#include "tools/json.h"

namespace shoal {
namespace {

using theory::Complex;

std::string Fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), f, v);
  return buf;
}
std::string G(double v) { return Fmt("%.4g", v); }

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
std::string ComplexJson(const Complex& c) {
  JsonWriter j;
  j.Num("re", c.real()).Num("im", c.imag());
  return j.Done();
}
std::string ComplexListJson(const std::vector<Complex>& v) {
  std::vector<std::string> items;
  for (const Complex& c : v) items.push_back(ComplexJson(c));
  return JsonWriter::List(items);
}
std::string MatrixJson(const Eigen::MatrixXd& m) {
  std::vector<std::string> rows;
  for (Eigen::Index i = 0; i < m.rows(); ++i) {
    std::vector<double> r(static_cast<std::size_t>(m.cols()));
    for (Eigen::Index k = 0; k < m.cols(); ++k) r[static_cast<std::size_t>(k)] = m(i, k);
    rows.push_back(JsonWriter::Array(r));
  }
  return JsonWriter::List(rows);
}
double OrNaN(const std::optional<double>& v) { return v ? *v : NAN; }
std::string OrNone(const std::optional<double>& v) { return v ? G(*v) : "none"; }

std::string DelayKindName(DelayKind k) {
  switch (k) {
    case DelayKind::kNone:
      return "none";
    case DelayKind::kConstant:
      return "constant";
    case DelayKind::kSinusoid:
      return "sinusoid";
    case DelayKind::kUniform:
      return "uniform";
  }
  return "?";
}
std::string DisturbanceName(DisturbanceKind k) {
  switch (k) {
    case DisturbanceKind::kNone:
      return "none";
    case DisturbanceKind::kPaperExample2:
      return "paper_example2";
    case DisturbanceKind::kOceanCurrent:
      return "ocean_current";
  }
  return "?";
}

/// Flag values: an error message naming the flag, or "".
std::string ValidateOptions(const DesignOptions& o) {
  auto positive = [](const char* flag, const std::optional<double>& v, const char* what) {
    if (v && !(std::isfinite(*v) && *v > 0.0)) {
      return std::string(flag) + " must be a positive number (got " + G(*v) + "): " + what;
    }
    return std::string();
  };
  std::string e;
  if (!(e = positive("--k1", o.k1, "the position gain k1 of protocol (10)")).empty()) return e;
  if (!(e = positive("--k2", o.k2, "the velocity gain k2 of protocol (10)")).empty()) return e;
  if (!(e = positive("--h", o.h_s,
                     "the delay bound h in seconds; for a delay-free analysis use a scenario "
                     "whose [channel.delay] model is \"none\""))
           .empty()) {
    return e;
  }
  if (o.kappa && !(std::isfinite(*o.kappa) && *o.kappa >= 0.0 && *o.kappa < 1.0)) {
    return "--kappa must be in [0, 1) (got " + G(*o.kappa) +
           "): the bound on d tau/dt of Assumption 3";
  }
  if (!(std::isfinite(o.alpha) && o.alpha > 0.0)) {
    return "--alpha must be a positive number (got " + G(o.alpha) + "): Theorem 1's alpha";
  }
  if (!(std::isfinite(o.beta) && o.beta > 0.0)) {
    return "--beta must be a positive number (got " + G(o.beta) + "): Theorem 1's beta";
  }
  if (o.rho0 && !(std::isfinite(*o.rho0) && *o.rho0 >= 0.0)) {
    return "--rho0 must be a number >= 0 (got " + G(*o.rho0) +
           "): the Lipschitz constant of the uncertain factor";
  }
  if (!(std::isfinite(o.safety) && o.safety >= 1.0)) {
    return "--safety must be a number >= 1 (got " + G(o.safety) +
           "): the required margin is safety x h";
  }
  if (!(std::isfinite(o.tune_horizon_s) && o.tune_horizon_s > 0.0)) {
    return "--tune-horizon must be a positive number of seconds (got " + G(o.tune_horizon_s) + ")";
  }
  if (o.empirical_duration_s != -1.0 &&
      !(std::isfinite(o.empirical_duration_s) && o.empirical_duration_s > 0.0)) {
    return "--empirical-duration must be a positive number of seconds (got " +
           G(o.empirical_duration_s) + ")";
  }
  return "";
}

// ---- Theorem 3 (LMI (27)-(28), every multiplier free, CSDP; design/theorem3) ----
// Adds the "theorem3" block: feasibility at the scenario's (h, kappa), max_delay_s by
// bisection, the paper's multipliers' best lambda_max(Xi), and writes --certificate.
// Returns true when the corrected LMI is feasible at (h, kappa) (checked with Eigen),
// false when it is infeasible or CSDP failed, std::nullopt when the theorem does not apply
// (no bound on tau', kappa >= 1, or an uncertain factor without Lipschitz data).
std::optional<bool> AddTheorem3Block(const Scenario& s, const Eigen::MatrixXd& H, double k1,
                                     double k2, double h_s, const std::optional<double>& kappa,
                                     const theory::Lipschitz& lip,
                                     const std::optional<double>& rho0_flag,
                                     const std::string& certificate, bool factor_covered,
                                     JsonWriter* json, std::ostream* text,
                                     std::optional<double>* max_delay_s, bool* write_failed) {
  JsonWriter t;
  std::ostream& txt = *text;
  txt << "theorem 3 (LMI (27)-(28) corrected, every multiplier free, CSDP)\n";
  std::string why_not;
  if (!kappa) {
    why_not = "the delay's rate is unbounded (uniform jitter draws a new delay per message)";
  } else if (*kappa >= 1.0) {
    why_not = "kappa = " + G(*kappa) + " >= 1 (Assumption 3 needs tau' <= kappa < 1)";
  } else if (!factor_covered) {
    why_not = s.disturbance.kind == DisturbanceKind::kOceanCurrent
                  ? "the ocean current has no Lipschitz bound of the form f(x_i) - f(x_0) "
                    "(pass --rho0 to assume one)"
                  : "the uncertain factor is not of the form f(x_i) - f(x_0) that Theorem 3 "
                    "covers (relative_to_leader = false; pass --rho0 to assume a bound)";
  }
  if (!why_not.empty()) {
    t.Bool("evaluated", false).Str("reason", why_not);
    json->Raw("theorem3", t.Done());
    txt << "  not evaluated: " << why_not << "\n";
    if (!certificate.empty()) {
      std::cerr << "shoal design: --certificate: Theorem 3 was not evaluated, nothing written\n";
    }
    return std::nullopt;
  }
  design::Theorem3Input in;
  in.H = H;
  in.k1 = k1;
  in.k2 = k2;
  in.h_s = h_s;
  in.kappa = *kappa;
  if (rho0_flag) {  // an assumed bound ||F|| <= rho0 (||x|| + ||v||): G = J = rho0 I
    in.lambda_G2 = in.lambda_J2 = *rho0_flag * *rho0_flag;
  } else {
    in.lambda_G2 = lip.lambda_max_G2;
    in.lambda_J2 = lip.lambda_max_J2;
  }
  const design::Theorem3Result at_h = design::CheckTheorem3(in);
  const design::MaxDelayResult maxd = design::MaxDelayTheorem3(in);
  const design::PaperMultipliersResult paper = design::PaperMultipliersMaxEigenvalue(in);
  if (maxd.input_valid) *max_delay_s = maxd.feasible_at_zero ? maxd.max_delay_s : 0.0;
  t.Bool("evaluated", true)
      .Num("h_s", h_s)
      .Num("kappa", *kappa)
      .Num("lambda_max_G2", in.lambda_G2)
      .Num("lambda_max_J2", in.lambda_J2)
      .Bool("feasible", at_h.certifies())
      .Int("csdp_return_code", at_h.csdp_return_code)
      .Str("csdp_status", at_h.csdp_status)
      .Num("margin", at_h.check.margin)
      .Str("message", at_h.message)
      .Bool("feasible_at_zero_delay", maxd.feasible_at_zero)
      .Num("max_delay_s", maxd.feasible_at_zero ? maxd.max_delay_s : 0.0)
      .Bool("max_delay_hit_cap", maxd.hit_cap)
      .Int("max_delay_solves", maxd.solves)
      .Int("max_delay_solver_failures", maxd.solver_failures)
      .Num("paper_multipliers_max_eigenvalue", paper.solved ? paper.max_eigenvalue : NAN)
      .Num("seconds", at_h.seconds + maxd.seconds + paper.seconds);
  txt << "  lambda_max(G^2) = " << G(in.lambda_G2) << ", lambda_max(J^2) = " << G(in.lambda_J2)
      << (rho0_flag ? " (from --rho0)" : "") << "\n";
  txt << "  at h = " << G(h_s) << " s, kappa = " << G(*kappa) << ": "
      << (at_h.certifies() ? "FEASIBLE (certified)" : "infeasible") << "; " << at_h.message
      << "\n";
  if (!maxd.input_valid) {
    txt << "  max delay: " << maxd.message << "\n";
  } else if (!maxd.feasible_at_zero) {
    txt << "  max delay: none (infeasible even at h = 0; docs/theory_theorem3.md says why)\n";
  } else {
    txt << "  max_delay_s = " << G(maxd.max_delay_s) << " s" << (maxd.hit_cap ? " (search cap)" : "")
        << " (" << maxd.solves << " solves)\n";
  }
  txt << "  paper's multipliers (X = 0.3I, Y = 0, Z = I, psi = 0.1I, Phi = 0.6I), best Q: "
      << (paper.solved ? "lambda_max(Xi) = " + G(paper.max_eigenvalue) +
                             (paper.max_eigenvalue < 0 ? " < 0 (certifies)" : " >= 0 (does not certify)")
                       : paper.message)
      << "\n";
  if (!certificate.empty()) {
    // The certificate at the scenario's h if there is one, else at the largest certified h.
    const design::Theorem3Result& r =
        at_h.certifies() || !maxd.feasible_at_zero ? at_h : maxd.at_max;
    std::string err;
    if (!design::WriteCertificate(r, certificate, &err)) {
      std::cerr << "shoal design: --certificate: " << err << "\n";
      *write_failed = true;
    } else {
      txt << "  certificate (h = " << G(r.input.h_s) << " s, "
          << (r.certifies() ? "feasible" : "NOT feasible: the solver's last matrices") << ") written to "
          << certificate << "\n";
      t.Str("certificate", certificate).Num("certificate_h_s", r.input.h_s);
    }
  }
  json->Raw("theorem3", t.Done());
  return at_h.certifies();
}

bool Tty() { return isatty(2) != 0; }

}  // namespace

int RunDesign(const DesignOptions& opt) {
  Scenario s;
  if (!LoadScenarioOrReport("shoal design", opt.scenario, &s)) return 2;
  if (const std::string e = ValidateOptions(opt); !e.empty()) {
    std::cerr << "shoal design: " << e << "\n";
    return 2;
  }

  if (!opt.certificate.empty()) {  // before the solves, not after them
    const bool existed = access(opt.certificate.c_str(), F_OK) == 0;
    FILE* f = std::fopen(opt.certificate.c_str(), "a");
    if (f && !existed) std::remove(opt.certificate.c_str());
    if (!f) {
      std::cerr << "shoal design: --certificate: " << opt.certificate
                << ": cannot write there (" << std::strerror(errno) << ")\n";
      return 2;
    }
    std::fclose(f);
  }
  const double k1 = opt.k1.value_or(s.k1);
  const double k2 = opt.k2.value_or(s.k2);
  s.k1 = k1;
  s.k2 = k2;
  const double alpha = opt.alpha, beta = opt.beta;

  // Topology.
  const Topology topo = Topology::Build(s.followers, s.edges, s.leader_links);
  const Eigen::MatrixXd H = topo.H();
  const std::vector<Complex> eig = theory::HEigenvalues(H);
  const std::vector<int> unreachable = topo.UnreachableFollowers();

  // Delays: the scenario's, or h (and kappa) from the flags describing one common delay.
  theory::DelayBounds delay = theory::DelayBoundsOf(s);
  const bool delay_overridden = opt.h_s.has_value() || opt.kappa.has_value();
  if (opt.h_s) delay.h_s = *opt.h_s;
  if (opt.kappa) delay.kappa = *opt.kappa;
  if (delay_overridden) {
    delay.time_varying = !delay.kappa || *delay.kappa > 0.0;
    delay.constant = !delay.time_varying;
  }

  // Uncertain factor.
  const theory::Lipschitz lip = theory::LipschitzOf(s.disturbance);
  if (opt.rho0 && lip.applicable && s.disturbance.kind != DisturbanceKind::kNone &&
      *opt.rho0 < lip.rho0) {
    std::cerr << "shoal design: --rho0 " << G(*opt.rho0) << " is below the uncertain factor's "
              << "own Lipschitz constant " << G(lip.rho0) << " (" << DisturbanceName(s.disturbance.kind)
              << "): a certificate would rest on a bound the model does not satisfy; give "
              << "--rho0 >= " << G(lip.rho0) << " or leave it out\n";
    return 2;
  }
  std::optional<double> rho0;
  if (opt.rho0) {
    rho0 = *opt.rho0;
  } else if (lip.applicable || s.disturbance.kind == DisturbanceKind::kPaperExample2) {
    rho0 = lip.rho0;
  }
  design::FactorKind factor = design::FactorKind::kNone;
  if (s.disturbance.kind != DisturbanceKind::kNone) {
    factor = lip.applicable ? design::FactorKind::kLipschitz : design::FactorKind::kUncovered;
  }
  // --rho0 states an assumed Lipschitz bound for the factor (or, with none, adds one).
  if (opt.rho0) factor = *opt.rho0 > 0.0 ? design::FactorKind::kLipschitz : factor;

  const std::optional<theory::Theorem1> t1 = theory::ComputeTheorem1(H, k1, k2, alpha, beta);
  std::optional<theory::Theorem2> t2;
  if (t1 && rho0) t2 = theory::ComputeTheorem2(*t1, alpha, beta, *rho0);
  const theory::DelayMargin margin = theory::ComputeDelayMargin(eig, k1, k2);

  JsonWriter j;
  std::ostringstream txt;
  j.Str("scenario", s.name).Int("followers", s.followers);
  {
    JsonWriter g;
    g.Num("k1", k1).Num("k2", k2).Num("alpha", alpha).Num("beta", beta);
    g.Str("source", opt.k1 || opt.k2 ? "flags" : "scenario");
    j.Raw("gains", g.Done());
  }
  txt << "shoal design: " << s.name << " (" << s.followers << " followers; k1 = " << G(k1)
      << ", k2 = " << G(k2) << "; alpha = " << G(alpha) << ", beta = " << G(beta) << ")\n";

  // Topology.
  j.Raw("H_eigenvalues", ComplexListJson(eig));
  {
    JsonWriter a;
    std::vector<double> ids(unreachable.begin(), unreachable.end());
    a.Bool("holds", unreachable.empty()).NumArray("unreachable_followers", ids);
    j.Raw("assumption1", a.Done());
  }
  txt << "topology\n  H eigenvalues: " << ComplexListText(eig) << "\n";
  if (unreachable.empty()) {
    txt << "  Assumption 1: holds (every follower has a directed path from the leader)\n";
  } else {
    txt << "  Assumption 1: FAILS: unreachable followers";
    for (int i : unreachable) txt << " " << i;
    txt << "\n";
  }

  // Delays.
  {
    JsonWriter d;
    d.Str("model", DelayKindName(s.delay.kind))
        .Bool("per_link_overrides", !s.links.empty())
        .Bool("overridden_by_flags", delay_overridden)
        .Num("h_s", delay.h_s)
        .Num("kappa", OrNaN(delay.kappa))
        .Bool("kappa_bounded", delay.kappa.has_value())
        .Bool("time_varying", delay.time_varying)
        .Bool("common_constant", delay.constant);
    j.Raw("delay", d.Done());
  }
  txt << "delays\n  "
      << (delay_overridden ? "from the flags" : "model " + DelayKindName(s.delay.kind))
      << (s.links.empty() || delay_overridden ? "" : " (with per-link overrides: max over links)")
      << ": h = " << G(delay.h_s) << " s, kappa = "
      << (delay.kappa ? G(*delay.kappa)
                      : std::string("unbounded (a new random delay per message: tau jumps)"))
      << (delay.time_varying ? " (time-varying)"
          : delay.constant   ? " (one constant delay)"
                             : " (different constant delays)")
      << "\n";

  // Uncertain factor.
  {
    JsonWriter u;
    u.Str("model", DisturbanceName(s.disturbance.kind));
    if (s.disturbance.kind == DisturbanceKind::kPaperExample2) {
      u.Bool("relative_to_leader", s.disturbance.relative_to_leader);
    }
    const bool have_lip = s.disturbance.kind != DisturbanceKind::kOceanCurrent;
    u.Num("lambda_max_G2", have_lip ? lip.lambda_max_G2 : NAN)
        .Num("lambda_max_J2", have_lip ? lip.lambda_max_J2 : NAN)
        .Num("rho0", OrNaN(rho0))
        .Str("rho0_source", opt.rho0 ? "flag" : (rho0 ? "scenario" : "none"))
        .Bool("theorems_apply", factor != design::FactorKind::kUncovered)
        .Str("note", lip.note);
    j.Raw("uncertain_factor", u.Done());
    txt << "uncertain factor\n  " << DisturbanceName(s.disturbance.kind);
    if (have_lip) {
      txt << ": lambda_max(G^2) = " << G(lip.lambda_max_G2)
          << ", lambda_max(J^2) = " << G(lip.lambda_max_J2);
    }
    txt << ", rho0 = " << OrNone(rho0) << (opt.rho0 ? " (--rho0)" : "") << "\n  " << lip.note
        << "\n";
  }

  // Theorem 1.
  if (t1) {
    JsonWriter t;
    std::vector<double> wev(t1->W_eigenvalues.data(),
                            t1->W_eigenvalues.data() + t1->W_eigenvalues.size());
    t.Raw("W", MatrixJson(t1->W))
        .NumArray("W_eigenvalues", wev)
        .Raw("M", MatrixJson(t1->M))
        .Raw("M2_eigenvalues", ComplexListJson(t1->M2_eigenvalues))
        .Num("lambda_max_W", t1->lambda_max_W)
        .Num("lambda_max_M2", t1->lambda_max_M2)
        .Num("lambda_max_MtM", t1->lambda_max_MtM)
        .Num("k1_min", OrNaN(t1->k1_min))
        .Num("k2_min", OrNaN(t1->k2_min))
        .Num("k1_min_corrected", OrNaN(t1->k1_min_corrected))
        .Num("k2_min_corrected", OrNaN(t1->k2_min_corrected))
        .Bool("Q_positive_definite", t1->Q_positive_definite)
        .Num("P_max_eigenvalue", t1->P_max_eigenvalue)
        .Bool("certifies", t1->certifies);
    j.Raw("theorem1", t.Done());
    txt << "theorem 1 (no delay, no uncertain factor)\n  W (W H + H^T W = I):\n";
    for (Eigen::Index i = 0; i < t1->W.rows(); ++i) {
      txt << "   ";
      for (Eigen::Index k = 0; k < t1->W.cols(); ++k) txt << Fmt(" %8.4f", t1->W(i, k));
      txt << "\n";
    }
    txt << "  W eigenvalues: ";
    for (Eigen::Index i = 0; i < t1->W_eigenvalues.size(); ++i) {
      txt << (i ? ", " : "") << Fmt("%.4f", t1->W_eigenvalues(i));
    }
    txt << "\n  M^2 eigenvalues: " << ComplexListText(t1->M2_eigenvalues)
        << "\n  lambda_max(W) = " << G(t1->lambda_max_W)
        << ", lambda_max(M^2) = " << G(t1->lambda_max_M2)
        << ", lambda_max(M^T M) = " << G(t1->lambda_max_MtM) << "\n";
    auto bound = [&](const char* what, const std::optional<double>& a,
                     const std::optional<double>& b, double lm) {
      txt << "  " << what << ": ";
      if (a) {
        txt << "k1 > " << G(*a) << ", k2 > " << G(*b) << "\n";
      } else {
        txt << "no gains (alpha beta = " << G(alpha * beta) << " <= " << G(lm) << ")\n";
      }
    };
    bound("paper's (15) with lambda_max(M^2)", t1->k1_min, t1->k2_min, t1->lambda_max_M2);
    bound("corrected, lambda_max(M^T M)", t1->k1_min_corrected, t1->k2_min_corrected,
          t1->lambda_max_MtM);
    txt << "  P = Q(A+B) + (A+B)^T Q: largest eigenvalue " << G(t1->P_max_eigenvalue)
        << (t1->certifies ? " < 0: certifies these gains (no delay, no uncertain factor)"
                          : (t1->Q_positive_definite ? " >= 0: does not certify these gains"
                                                     : "; Q is not positive definite (k1 <= "
                                                       "alpha^2): does not certify"))
        << "\n";
  } else {
    j.Raw("theorem1", "null");
    txt << "theorem 1: not applicable (an eigenvalue of H has real part <= 0: no W)\n";
  }

  // Theorem 2.
  if (t2) {
    JsonWriter t;
    t.Num("rho0", t2->rho0)
        .Num("k11", t2->k11)
        .Num("k21", t2->k21)
        .Num("k12", OrNaN(t2->k12))
        .Num("k22", OrNaN(t2->k22))
        .Num("k1_min", OrNaN(t2->k1_min))
        .Num("k2_min", OrNaN(t2->k2_min))
        .Num("k11_corrected", t2->k11_corrected)
        .Num("k21_corrected", t2->k21_corrected)
        .Num("k12_corrected", OrNaN(t2->k12_corrected))
        .Num("k22_corrected", OrNaN(t2->k22_corrected))
        .Num("k1_min_corrected", OrNaN(t2->k1_min_corrected))
        .Num("k2_min_corrected", OrNaN(t2->k2_min_corrected))
        .Num("P_tilde_max_eigenvalue", t2->P_tilde_max_eigenvalue)
        .Bool("certifies", t2->certifies);
    j.Raw("theorem2", t.Done());
    txt << "theorem 2 (no delay, uncertain factor with rho0 = " << G(t2->rho0) << ")\n"
        << "  paper's (20)-(21): k11 = " << G(t2->k11) << ", k21 = " << G(t2->k21)
        << ", k12 = " << OrNone(t2->k12) << ", k22 = " << OrNone(t2->k22);
    if (t2->k1_min) {
      txt << "  =>  k1 > " << G(*t2->k1_min) << ", k2 > " << G(*t2->k2_min) << "\n";
    } else {
      txt << "  =>  no gains (alpha beta - 2 lambda_max(M^2) = "
          << G(alpha * beta - 2 * t1->lambda_max_M2) << " <= 0)\n";
    }
    txt << "  corrected (factor 2, M^T M): k11 = " << G(t2->k11_corrected)
        << ", k21 = " << G(t2->k21_corrected) << ", k12 = " << OrNone(t2->k12_corrected)
        << ", k22 = " << OrNone(t2->k22_corrected);
    if (t2->k1_min_corrected) {
      txt << "  =>  k1 > " << G(*t2->k1_min_corrected) << ", k2 > " << G(*t2->k2_min_corrected)
          << "\n";
    } else {
      txt << "  =>  no gains (alpha beta - 2 lambda_max(M^T M) = "
          << G(alpha * beta - 2 * t1->lambda_max_MtM) << " <= 0)\n";
    }
    txt << "  P~ for these gains: largest eigenvalue " << G(t2->P_tilde_max_eigenvalue)
        << (t2->certifies ? " < 0: certifies them (no delay)" : ": does not certify them") << "\n";
  } else {
    j.Raw("theorem2", "null");
    txt << "theorem 2: not evaluated (no rho0 for this uncertain factor; give --rho0)\n";
  }

  // Theorem 3 (wired in by design/theorem3; see AddTheorem3Block).
  std::optional<double> theorem3_max_delay;
  bool certificate_failed = false;
  const std::optional<bool> theorem3_certified =
      AddTheorem3Block(s, H, k1, k2, delay.h_s, delay.kappa, lip, opt.rho0, opt.certificate,
                       factor != design::FactorKind::kUncovered, &j, &txt, &theorem3_max_delay,
                       &certificate_failed);

  // Exact delay margin.
  {
    j.Num("delay_margin_s", margin.stable_at_zero ? margin.tau_s : 0.0);
    JsonWriter d;
    d.Bool("stable_at_zero_delay", margin.stable_at_zero);
    if (margin.critical >= 0) {
      const theory::EigenMargin& c = margin.per_eigenvalue[margin.critical];
      d.Raw("critical_eigenvalue", ComplexJson(c.lambda))
          .Num("crossing_frequency_rad_s", std::abs(c.omega_rad_s));
    }
    d.Num("margin_over_h", delay.h_s > 0 ? margin.tau_s / delay.h_s : NAN);
    std::vector<std::string> per;
    for (const theory::EigenMargin& e : margin.per_eigenvalue) {
      JsonWriter p;
      p.Raw("lambda", ComplexJson(e.lambda))
          .Bool("stable_at_zero_delay", e.stable_at_zero)
          .Num("tau_s", e.tau_s)
          .Num("crossing_frequency_rad_s", std::abs(e.omega_rad_s));
      per.push_back(p.Done());
    }
    d.Raw("per_eigenvalue", JsonWriter::List(per));
    j.Raw("delay_margin", d.Done());
    txt << "exact delay margin (one constant delay on own and neighbour states, no uncertain "
           "factor)\n";
    if (!margin.stable_at_zero) {
      txt << "  UNSTABLE without delay: margin 0\n";
    } else {
      const theory::EigenMargin& c = margin.per_eigenvalue[margin.critical];
      txt << "  delay_margin_s = " << Fmt("%.4f", margin.tau_s) << " s (eigenvalue "
          << ComplexText(c.lambda) << ", crossing at " << G(std::abs(c.omega_rad_s)) << " rad/s)";
      if (delay.h_s > 0) txt << " = " << Fmt("%.2f", margin.tau_s / delay.h_s) << " x h";
      txt << "\n  per eigenvalue:";
      for (std::size_t i = 0; i < margin.per_eigenvalue.size(); ++i) {
        const theory::EigenMargin& e = margin.per_eigenvalue[i];
        txt << (i ? "; " : " ") << ComplexText(e.lambda) << ": " << Fmt("%.4f", e.tau_s) << " s";
      }
      txt << "\n";
    }
  }

  // The same with the uncertain factor linearised (an indication).
  const bool factor_margin_shown = s.disturbance.kind != DisturbanceKind::kNone && lip.slopes_known;
  const theory::FactorDelayMargin factor_margin =
      theory::ComputeFactorDelayMargin(eig, k1, k2, lip);
  if (factor_margin_shown) {
    const theory::FactorDelayMargin& f = factor_margin;
    static const char* kComponent[] = {"x", "y", "z", "theta", "psi"};
    JsonWriter d;
    d.Bool("stable_at_zero_delay", f.stable_at_zero)
        .Num("tau_s", f.stable_at_zero ? f.tau_s : 0.0)
        .Raw("critical_eigenvalue", ComplexJson(f.lambda))
        .Str("critical_component", f.component >= 0 ? kComponent[f.component] : "")
        .Num("x_slope", f.x_slope)
        .Num("v_slope", f.v_slope)
        .Str("meaning",
             "exact constant-delay margin of the loop with the uncertain factor "
             "linearised, slopes frozen at the worst corner of their ranges: an "
             "indication, not a certificate");
    j.Raw("delay_margin_with_factor", d.Done());
    txt << "delay margin with the uncertain factor linearised (slopes frozen at their worst "
           "corner; indication only)\n  ";
    if (!f.stable_at_zero) {
      txt << "UNSTABLE without delay: component " << kComponent[f.component] << " with slope "
          << G(f.v_slope) << " on its rate, eigenvalue " << ComplexText(f.lambda)
          << " (lambda k2 - slope has no damping left)\n";
    } else {
      txt << Fmt("%.4f", f.tau_s) << " s (component " << kComponent[f.component] << ", eigenvalue "
          << ComplexText(f.lambda) << ", slopes dx " << G(f.x_slope) << ", dv " << G(f.v_slope)
          << ")";
      if (delay.h_s > 0) txt << " = " << Fmt("%.2f", f.tau_s / delay.h_s) << " x h";
      txt << "\n";
    }
  }

  // Empirical margin.
  if (opt.empirical) {
    design::EmpiricalMarginOptions eo;
    eo.duration_s = opt.empirical_duration_s;
    eo.initial_upper_s = margin.stable_at_zero ? 2.0 * margin.tau_s : 1.0;
    if (!opt.json && Tty())
      std::fprintf(stderr, "shoal design: empirical margin (bisection over shoal sim runs)...\n");
    const auto t0 = std::chrono::steady_clock::now();
    const design::EmpiricalMargin em = design::FindEmpiricalMargin(s, eo);
    const double wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const std::string model = design::EmpiricalModelDescription(s, em.duration_s);
    j.Num("empirical_margin_s", em.converges_without_delay ? em.margin_s : 0.0);
    JsonWriter e;
    e.Bool("converges_at_one_period", em.converges_without_delay)
        .Num("first_failing_delay_s", em.capped ? NAN : em.first_failing_s)
        .Bool("capped", em.capped)
        .Num("cap_s", em.cap_s)
        .Num("resolution_s", em.period_s)
        .Num("run_duration_s", em.duration_s)
        .Int("runs", em.runs)
        .Num("wall_time_s", wall)
        .Str("model", model);
    j.Raw("empirical", e.Done());
    txt << "empirical margin (--empirical)\n";
    if (!em.converges_without_delay) {
      txt << "  does NOT converge even with the minimum delay of one control period ("
          << G(em.period_s) << " s)\n";
    } else if (em.capped) {
      txt << "  converges at every delay tried, up to " << G(em.cap_s)
          << " s (the neighbour timeout limits the search)\n";
    } else {
      txt << "  empirical_margin_s = " << Fmt("%.3f", em.margin_s) << " s (converges; does not at "
          << Fmt("%.3f", em.first_failing_s) << " s; resolution one control period)\n";
    }
    txt << "  " << em.runs << " runs of " << G(em.duration_s) << " s in " << Fmt("%.1f", wall)
        << " s wall; model: " << model << "\n";
  }

  // Tuning.
  if (opt.tune) {
    design::TuneOptions to;
    to.safety = opt.safety;
    to.horizon_s = opt.tune_horizon_s;
    to.cost = opt.tune_cost == "ise"            ? design::CostKind::kIse
              : opt.tune_cost == "position_ise" ? design::CostKind::kPositionIse
                                                : design::CostKind::kItse;
    if (!opt.json && Tty())
      std::fprintf(stderr, "shoal design: tuning k1, k2 with Ceres (4 starts)...\n");
    const auto t0 = std::chrono::steady_clock::now();
    const design::TuneResult tr = design::Tune(s, eig, delay.h_s, to);
    const double wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    auto point = [&](const design::TunePoint& p) {
      JsonWriter w;
      w.Num("k1", p.k1).Num("k2", p.k2).Num("delay_margin_s", p.margin_s);
      if (factor_margin_shown) {
        const theory::FactorDelayMargin f = theory::ComputeFactorDelayMargin(eig, p.k1, p.k2, lip);
        w.Num("delay_margin_with_factor_s", f.stable_at_zero ? f.tau_s : 0.0);
      }
      w.Num("cost", p.cost)
          .Num("position_ise_m2s", p.position_ise_m2s)
          .Bool("converged", p.converged)
          .Num("convergence_time_s", p.converged ? p.convergence_time_s : NAN);
      return w.Done();
    };
    JsonWriter t;
    t.Bool("ok", tr.ok)
        .Num("safety", opt.safety)
        .Num("required_margin_s", tr.required_margin_s)
        .Num("horizon_s", tr.horizon_s)
        .Str("cost_kind", design::CostName(to.cost))
        .Raw("before", point(tr.before))
        .Bool("before_meets_requirement", tr.before_feasible);
    if (tr.ok) t.Raw("after", point(tr.after));
    std::vector<std::string> starts;
    for (const design::TuneStart& st : tr.starts) {
      JsonWriter w;
      w.Num("k1_start", st.k1_start)
          .Num("k2_start", st.k2_start)
          .Num("k1", st.k1)
          .Num("k2", st.k2)
          .Num("cost", st.usable ? st.cost : NAN)
          .Int("iterations", st.iterations)
          .Bool("usable", st.usable)
          .Str("message", st.message);
      starts.push_back(w.Done());
    }
    t.Raw("starts", JsonWriter::List(starts)).Int("sim_runs", tr.sim_runs).Num("wall_time_s", wall);
    if (!tr.ok) t.Str("message", tr.message);
    j.Raw("tune", t.Done());

    auto line = [&](const char* name, const design::TunePoint& p) {
      txt << "  " << name << ": k1 = " << G(p.k1) << ", k2 = " << G(p.k2) << ", margin "
          << Fmt("%.4f", p.margin_s) << " s";
      if (factor_margin_shown) {
        const theory::FactorDelayMargin f = theory::ComputeFactorDelayMargin(eig, p.k1, p.k2, lip);
        txt << " (with the factor linearised: " << Fmt("%.4f", f.stable_at_zero ? f.tau_s : 0.0)
            << " s)";
      }
      txt << ", cost " << G(p.cost) << " (position ISE " << G(p.position_ise_m2s) << " m^2 s), "
          << (p.converged ? "converged at " + Fmt("%.2f", p.convergence_time_s) + " s"
                          : std::string("did NOT converge"))
          << "\n";
    };
    const std::string pt = "(e_p/" + G(s.metrics.position_tol_m) + " m)^2";
    const std::string vt = "(e_v/" + G(s.metrics.velocity_tol_mps) + " m/s)^2";
    const std::string integrand = to.cost == design::CostKind::kPositionIse ? "e_p^2 dt"
                                  : to.cost == design::CostKind::kIse
                                      ? pt + " + " + vt + " dt"
                                      : "t (" + pt + " + " + vt + ") dt";
    txt << "tune (--tune, cost " << design::CostName(to.cost) << ": integral of " << integrand
        << " over " << G(tr.horizon_s) << " s, summed over followers; margin >= " << G(opt.safety)
        << " x max(h, control period) = " << G(tr.required_margin_s) << " s)\n";
    line("before", tr.before);
    if (!tr.before_feasible)
      txt << "          (the scenario's gains do not meet the margin requirement)\n";
    if (tr.ok) {
      line("after ", tr.after);
    } else {
      txt << "  FAILED: " << tr.message << "\n";
    }
    txt << "  starts:";
    for (const design::TuneStart& st : tr.starts) {
      txt << " (" << G(st.k1_start) << ", " << G(st.k2_start) << ") -> ";
      if (st.usable) {
        txt << "(" << G(st.k1) << ", " << G(st.k2) << ") cost " << G(st.cost) << ";";
      } else {
        txt << "not usable (" << st.message << ");";
      }
    }
    txt << "\n  " << tr.sim_runs << " simulations in " << Fmt("%.1f", wall) << " s wall"
        << " (convergence times from full " << G(s.duration_s) << " s runs)\n";
  }

  // Verdict.
  design::VerdictInput vi;
  vi.k1 = k1;
  vi.k2 = k2;
  vi.h_s = delay.h_s;
  vi.kappa = delay.kappa;
  vi.delay_time_varying = delay.time_varying;
  vi.delay_common_constant = delay.constant;
  vi.factor = factor;
  vi.rho0 = rho0.value_or(0.0);
  vi.theorem1 = t1 ? &*t1 : nullptr;
  vi.theorem2 = t2 ? &*t2 : nullptr;
  vi.margin = &margin;
  vi.factor_margin = factor_margin_shown ? &factor_margin : nullptr;
  vi.safety = opt.safety;
  vi.theorem3_certified = theorem3_certified;
  vi.theorem3_max_delay_s = theorem3_max_delay;
  const design::Verdict v = design::Decide(vi);
  {
    JsonWriter w;
    w.Bool("certified", v.certified)
        .Str("by", v.by)
        .Str("reason", v.reason)
        .Str("advice", v.advice)
        .Num("margin_over_h", v.margin_over_h)
        .Str("line", v.Line());
    j.Raw("verdict", w.Done());
  }
  txt << v.Line() << "\n";

  if (opt.json) {
    std::cout << j.Done() << "\n";
  } else {
    std::cout << txt.str();
  }
  if (certificate_failed) return 2;
  return v.certified ? 0 : 1;
}

}  // namespace shoal

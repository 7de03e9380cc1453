// The JSON rendering of a DesignReport. Keys keep their insertion order (ordered_json) so
// the object reads in the order of the text report; nlohmann writes non-finite numbers as
// null and finite ones in their shortest round-trip form.
#include <cmath>

#include "design/report.h"

namespace shoal {
namespace design {
namespace {

using Json = nlohmann::ordered_json;
using theory::Complex;

Json Number(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }
Json Number(const std::optional<double>& v) { return v ? Number(*v) : Json(nullptr); }

Json ComplexJson(const Complex& c) {
  Json j;
  j["re"] = Number(c.real());
  j["im"] = Number(c.imag());
  return j;
}
Json ComplexListJson(const std::vector<Complex>& v) {
  Json a = Json::array();
  for (const Complex& c : v) a.push_back(ComplexJson(c));
  return a;
}
Json MatrixJson(const Eigen::MatrixXd& m) {
  Json rows = Json::array();
  for (Eigen::Index i = 0; i < m.rows(); ++i) {
    Json row = Json::array();
    for (Eigen::Index k = 0; k < m.cols(); ++k) row.push_back(Number(m(i, k)));
    rows.push_back(row);
  }
  return rows;
}

Json DelayJson(const DesignReport& r) {
  Json d;
  d["model"] = DelayKindName(r.delay_model);
  d["per_link_overrides"] = r.per_link_overrides;
  d["overridden_by_flags"] = r.delay_from_flags;
  d["h_s"] = Number(r.delay.h_s);
  d["kappa"] = Number(r.delay.kappa);
  d["kappa_bounded"] = r.delay.kappa.has_value();
  d["time_varying"] = r.delay.time_varying;
  d["common_constant"] = r.delay.constant;
  return d;
}

Json FactorJson(const DesignReport& r) {
  Json u;
  u["model"] = DisturbanceName(r.disturbance);
  if (r.disturbance == DisturbanceKind::kPaperExample2) {
    u["relative_to_leader"] = r.relative_to_leader;
  }
  const bool have_lip = r.disturbance != DisturbanceKind::kOceanCurrent;
  u["lambda_max_G2"] = have_lip ? Number(r.lipschitz.lambda_max_G2) : Json(nullptr);
  u["lambda_max_J2"] = have_lip ? Number(r.lipschitz.lambda_max_J2) : Json(nullptr);
  u["rho0"] = Number(r.rho0);
  u["rho0_source"] = r.rho0_from_flag ? "flag" : (r.rho0 ? "scenario" : "none");
  u["theorems_apply"] = r.factor != FactorKind::kUncovered;
  u["note"] = r.lipschitz.note;
  return u;
}

Json Theorem1Json(const theory::Theorem1& t1) {
  Json t;
  t["W"] = MatrixJson(t1.W);
  Json wev = Json::array();
  for (Eigen::Index i = 0; i < t1.W_eigenvalues.size(); ++i) wev.push_back(Number(t1.W_eigenvalues(i)));
  t["W_eigenvalues"] = wev;
  t["M"] = MatrixJson(t1.M);
  t["M2_eigenvalues"] = ComplexListJson(t1.M2_eigenvalues);
  t["lambda_max_W"] = Number(t1.lambda_max_W);
  t["lambda_max_M2"] = Number(t1.lambda_max_M2);
  t["lambda_max_MtM"] = Number(t1.lambda_max_MtM);
  t["k1_min"] = Number(t1.k1_min);
  t["k2_min"] = Number(t1.k2_min);
  t["k1_min_corrected"] = Number(t1.k1_min_corrected);
  t["k2_min_corrected"] = Number(t1.k2_min_corrected);
  t["Q_positive_definite"] = t1.Q_positive_definite;
  t["P_max_eigenvalue"] = Number(t1.P_max_eigenvalue);
  t["certifies"] = t1.certifies;
  return t;
}

Json Theorem2Json(const theory::Theorem2& t2) {
  Json t;
  t["rho0"] = Number(t2.rho0);
  t["k11"] = Number(t2.k11);
  t["k21"] = Number(t2.k21);
  t["k12"] = Number(t2.k12);
  t["k22"] = Number(t2.k22);
  t["k1_min"] = Number(t2.k1_min);
  t["k2_min"] = Number(t2.k2_min);
  t["k11_corrected"] = Number(t2.k11_corrected);
  t["k21_corrected"] = Number(t2.k21_corrected);
  t["k12_corrected"] = Number(t2.k12_corrected);
  t["k22_corrected"] = Number(t2.k22_corrected);
  t["k1_min_corrected"] = Number(t2.k1_min_corrected);
  t["k2_min_corrected"] = Number(t2.k2_min_corrected);
  t["P_tilde_max_eigenvalue"] = Number(t2.P_tilde_max_eigenvalue);
  t["certifies"] = t2.certifies;
  return t;
}

Json Theorem3Json(const Theorem3Section& s) {
  Json t;
  t["evaluated"] = s.evaluated;
  if (!s.evaluated) {
    t["reason"] = s.not_evaluated_reason;
    return t;
  }
  const MaxDelayResult& maxd = s.max_delay;
  t["h_s"] = Number(s.input.h_s);
  t["kappa"] = Number(s.input.kappa);
  t["lambda_max_G2"] = Number(s.input.lambda_G2);
  t["lambda_max_J2"] = Number(s.input.lambda_J2);
  t["feasible"] = s.at_h.certifies();
  t["csdp_return_code"] = s.at_h.csdp_return_code;
  t["csdp_status"] = s.at_h.csdp_status;
  t["margin"] = Number(s.at_h.check.margin);
  t["message"] = s.at_h.message;
  t["feasible_at_zero_delay"] = maxd.feasible_at_zero;
  t["max_delay_s"] = Number(maxd.feasible_at_zero ? maxd.max_delay_s : 0.0);
  t["max_delay_hit_cap"] = maxd.hit_cap;
  t["max_delay_solves"] = maxd.solves;
  t["max_delay_solver_failures"] = maxd.solver_failures;
  t["paper_multipliers_max_eigenvalue"] = s.paper.solved ? Number(s.paper.max_eigenvalue)
                                                          : Json(nullptr);
  t["seconds"] = Number(s.at_h.seconds + maxd.seconds + s.paper.seconds);
  if (!s.certificate_path.empty()) {
    t["certificate"] = s.certificate_path;
    t["certificate_h_s"] = Number(s.CertificateResult().input.h_s);
  }
  return t;
}

Json DelayMarginJson(const DesignReport& r) {
  const theory::DelayMargin& m = r.margin;
  Json d;
  d["stable_at_zero_delay"] = m.stable_at_zero;
  if (m.critical >= 0) {
    const theory::EigenMargin& c = m.per_eigenvalue[m.critical];
    d["critical_eigenvalue"] = ComplexJson(c.lambda);
    d["crossing_frequency_rad_s"] = Number(std::abs(c.omega_rad_s));
  }
  d["margin_over_h"] = r.delay.h_s > 0 ? Number(m.tau_s / r.delay.h_s) : Json(nullptr);
  Json per = Json::array();
  for (const theory::EigenMargin& e : m.per_eigenvalue) {
    Json p;
    p["lambda"] = ComplexJson(e.lambda);
    p["stable_at_zero_delay"] = e.stable_at_zero;
    p["tau_s"] = Number(e.tau_s);
    p["crossing_frequency_rad_s"] = Number(std::abs(e.omega_rad_s));
    per.push_back(p);
  }
  d["per_eigenvalue"] = per;
  return d;
}

Json FactorMarginJson(const theory::FactorDelayMargin& f) {
  static const char* kComponent[] = {"x", "y", "z", "theta", "psi"};
  Json d;
  d["stable_at_zero_delay"] = f.stable_at_zero;
  d["tau_s"] = Number(f.stable_at_zero ? f.tau_s : 0.0);
  d["critical_eigenvalue"] = ComplexJson(f.lambda);
  d["critical_component"] = f.component >= 0 ? kComponent[f.component] : "";
  d["x_slope"] = Number(f.x_slope);
  d["v_slope"] = Number(f.v_slope);
  d["meaning"] =
      "exact constant-delay margin of the loop with the uncertain factor linearised, slopes "
      "frozen at the worst corner of their ranges: an indication, not a certificate";
  return d;
}

Json CommonLyapunovJson(const CommonLyapunov& c) {
  Json j;
  j["attempted"] = c.attempted;
  if (!c.attempted) j["reason"] = c.not_attempted_reason;
  j["found"] = c.found();
  j["eps"] = Number(c.eps);
  j["csdp_return_code"] = c.csdp_return_code;
  j["csdp_status"] = c.csdp_status;
  j["seconds"] = Number(c.seconds);
  j["P_min_eigenvalue"] = c.P.size() > 0 ? Number(c.check.P_min_eigenvalue) : Json(nullptr);
  Json m = Json::array();
  for (double v : c.check.max_eigenvalues) m.push_back(Number(v));
  j["max_eigenvalues"] = m;
  j["P"] = c.found() ? MatrixJson(c.P) : Json(nullptr);
  return j;
}

Json SwitchingJson(const DesignReport& r, const SwitchingSection& sw) {
  Json topologies = Json::array();
  for (const TopologyResult& t : sw.topologies) {
    Json o;
    o["index"] = t.index;
    o["from"] = TopologySource(t);
    o["event_index"] = t.event_index;
    o["event_line"] = t.event_line;
    o["at_s"] = Number(t.at_s);
    o["H_eigenvalues"] = ComplexListJson(t.eigenvalues);
    o["assumption1"] = {{"holds", t.unreachable_followers.empty()},
                        {"unreachable_followers", t.unreachable_followers}};
    o["theorem1"] = {{"available", t.theorem1_available},
                     {"certifies", t.theorem1_certifies},
                     {"P_max_eigenvalue",
                      t.theorem1_available ? Number(t.theorem1_P_max_eigenvalue) : Json(nullptr)}};
    o["stable_at_zero_delay"] = t.margin.stable_at_zero;
    o["delay_margin_s"] = Number(t.margin_s());
    topologies.push_back(o);
  }
  Json j;
  j["topologies"] = topologies;
  j["critical_topology"] = sw.critical;
  j["min_delay_margin_s"] = Number(sw.min_margin_s);
  j["h_below_min_margin"] = r.delay.h_s < sw.min_margin_s;
  j["common_lyapunov"] = CommonLyapunovJson(sw.common);
  return j;
}

Json FormationDelayJson(const DesignReport& r, const FormationDelay& f) {
  const double m = r.GoverningMarginS();
  Json j;
  j["acoustic_links"] = f.acoustic_links;
  j["in_formation_s"] = Number(f.in_formation_s);
  j["link"] = {f.from, f.to};
  j["range_m"] = Number(f.range_m);
  j["beyond_range_links"] = f.beyond_range_links;
  j["model_bound_s"] = Number(f.model_bound_s);
  j["margin_s"] = Number(m);
  j["in_formation_below_margin"] = f.in_formation_s < m;
  j["model_bound_below_margin"] = f.model_bound_s < m;
  return j;
}

Json EmpiricalJson(const EmpiricalSection& s) {
  const EmpiricalMargin& em = s.margin;
  Json e;
  e["converges_at_one_period"] = em.converges_without_delay;
  e["first_failing_delay_s"] = em.capped ? Json(nullptr) : Number(em.first_failing_s);
  e["capped"] = em.capped;
  e["cap_s"] = Number(em.cap_s);
  e["resolution_s"] = Number(em.period_s);
  e["run_duration_s"] = Number(em.duration_s);
  e["runs"] = em.runs;
  e["wall_time_s"] = Number(s.wall_s);
  e["model"] = s.model;
  return e;
}

Json TunePointJson(const DesignReport& r, const TunePoint& p, double factor_margin_s) {
  Json w;
  w["k1"] = Number(p.k1);
  w["k2"] = Number(p.k2);
  w["delay_margin_s"] = Number(p.margin_s);
  if (r.factor_margin_shown) w["delay_margin_with_factor_s"] = Number(factor_margin_s);
  w["cost"] = Number(p.cost);
  w["position_ise_m2s"] = Number(p.position_ise_m2s);
  w["converged"] = p.converged;
  w["convergence_time_s"] = p.converged ? Number(p.convergence_time_s) : Json(nullptr);
  return w;
}

Json TuneJson(const DesignReport& r, const TuneSection& s) {
  const TuneResult& tr = s.result;
  Json t;
  t["ok"] = tr.ok;
  t["safety"] = Number(r.safety);
  t["required_margin_s"] = Number(tr.required_margin_s);
  t["horizon_s"] = Number(tr.horizon_s);
  t["cost_kind"] = CostName(s.cost);
  t["before"] = TunePointJson(r, tr.before, s.before_factor_margin_s);
  t["before_meets_requirement"] = tr.before_feasible;
  if (tr.ok) t["after"] = TunePointJson(r, tr.after, s.after_factor_margin_s);
  Json starts = Json::array();
  for (const TuneStart& st : tr.starts) {
    Json w;
    w["k1_start"] = Number(st.k1_start);
    w["k2_start"] = Number(st.k2_start);
    w["k1"] = Number(st.k1);
    w["k2"] = Number(st.k2);
    w["cost"] = st.usable ? Number(st.cost) : Json(nullptr);
    w["iterations"] = st.iterations;
    w["usable"] = st.usable;
    w["message"] = st.message;
    starts.push_back(w);
  }
  t["starts"] = starts;
  t["sim_runs"] = tr.sim_runs;
  t["wall_time_s"] = Number(s.wall_s);
  if (!tr.ok) t["message"] = tr.message;
  return t;
}

Json AdviceJson(const AdviceSection& a) {
  Json j;
  j["evaluated"] = a.evaluated;
  if (!a.evaluated) {
    j["reason"] = a.not_evaluated_reason;
    return j;
  }
  const GainAdvice& g = a.advice;
  j["k1"] = Number(g.k1);
  j["k2"] = Number(g.k2);
  j["scale"] = Number(g.scale);
  j["certified_at_h"] = g.certified_at_h;
  j["theorem3_max_delay_s"] = Number(g.theorem3_max_delay_s);
  j["delay_margin_s"] = Number(g.delay_margin_s);
  j["delay_margin_with_factor_s"] =
      g.delay_margin_with_factor_s >= 0.0 ? Number(g.delay_margin_with_factor_s) : Json(nullptr);
  j["how"] = g.how;
  j["solves"] = g.solves;
  j["seconds"] = Number(g.seconds);
  if (!a.scenario_written.empty()) j["scenario_written"] = a.scenario_written;
  return j;
}

Json VerdictJson(const Verdict& v) {
  Json w;
  w["certified"] = v.certified;
  w["by"] = v.by;
  w["reason"] = v.reason;
  w["advice"] = v.advice;
  w["margin_over_h"] = Number(v.margin_over_h);
  w["line"] = v.Line();
  return w;
}

}  // namespace

nlohmann::ordered_json DesignReportJson(const DesignReport& r) {
  Json j;
  j["scenario"] = r.scenario_name;
  j["followers"] = r.followers;
  j["gains"] = {{"k1", Number(r.k1)},       {"k2", Number(r.k2)},
                {"alpha", Number(r.alpha)}, {"beta", Number(r.beta)},
                {"source", r.gains_from_flags ? "flags" : "scenario"}};
  j["H_eigenvalues"] = ComplexListJson(r.eigenvalues);
  j["assumption1"] = {{"holds", r.unreachable_followers.empty()},
                      {"unreachable_followers", r.unreachable_followers}};
  j["delay"] = DelayJson(r);
  j["uncertain_factor"] = FactorJson(r);
  j["theorem1"] = r.theorem1 ? Theorem1Json(*r.theorem1) : Json(nullptr);
  j["theorem2"] = r.theorem2 ? Theorem2Json(*r.theorem2) : Json(nullptr);
  j["theorem3"] = Theorem3Json(r.theorem3);
  j["delay_margin_s"] = Number(r.margin.stable_at_zero ? r.margin.tau_s : 0.0);
  j["delay_margin"] = DelayMarginJson(r);
  if (r.factor_margin_shown) j["delay_margin_with_factor"] = FactorMarginJson(r.factor_margin);
  if (r.switching) j["switching"] = SwitchingJson(r, *r.switching);
  if (r.formation_delay) j["acoustic_formation_delay"] = FormationDelayJson(r, *r.formation_delay);
  if (r.empirical) {
    const EmpiricalMargin& em = r.empirical->margin;
    j["empirical_margin_s"] = Number(em.converges_without_delay ? em.margin_s : 0.0);
    j["empirical"] = EmpiricalJson(*r.empirical);
  }
  if (r.tune) j["tune"] = TuneJson(r, *r.tune);
  if (r.advice) j["advised_gains"] = AdviceJson(*r.advice);
  j["verdict"] = VerdictJson(r.verdict);
  return j;
}

}  // namespace design
}  // namespace shoal

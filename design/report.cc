#include "design/report.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>

#include "core/swarm.h"
#include "core/timeline.h"
#include "core/topology.h"
#include "design/format.h"

namespace shoal {
namespace design {
namespace {

double WallSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

std::string PositiveError(const char* flag, const std::optional<double>& v, const char* what) {
  if (v && !(std::isfinite(*v) && *v > 0.0)) {
    return std::string(flag) + " must be a positive number (got " + G4(*v) + "): " + what;
  }
  return "";
}

/// The scenario loader's own limits, so that a flag cannot give what a file may not: gains
/// beyond 1e6 overflow the delay margin's discriminant, delays beyond 1e9 s any run.
std::string AtMostError(const char* flag, const std::optional<double>& v, double limit,
                        const char* what) {
  if (v && *v > limit) {
    return std::string(flag) + " must be at most " + G4(limit) + " (got " + G4(*v) + "): " + what;
  }
  return "";
}

/// The request's values alone: an error message naming the flag, or "".
std::string ValueError(const DesignRequest& o) {
  std::string e;
  if (!(e = PositiveError("--k1", o.k1, "the position gain k1 of protocol (10)")).empty()) return e;
  if (!(e = PositiveError("--k2", o.k2, "the velocity gain k2 of protocol (10)")).empty()) return e;
  if (!(e = PositiveError("--h", o.h_s,
                          "the delay bound h in seconds; for a delay-free analysis use a scenario "
                          "whose [channel.delay] model is \"none\""))
           .empty()) {
    return e;
  }
  if (!(e = AtMostError("--k1", o.k1, 1e6, "the limit of control.k1 in a scenario")).empty()) return e;
  if (!(e = AtMostError("--k2", o.k2, 1e6, "the limit of control.k2 in a scenario")).empty()) return e;
  if (!(e = AtMostError("--h", o.h_s, 1e9, "the limit of a delay in a scenario")).empty()) return e;
  if (o.kappa && !(std::isfinite(*o.kappa) && *o.kappa >= 0.0 && *o.kappa < 1.0)) {
    return "--kappa must be in [0, 1) (got " + G4(*o.kappa) +
           "): the bound on d tau/dt of Assumption 3";
  }
  if (!(std::isfinite(o.alpha) && o.alpha > 0.0)) {
    return "--alpha must be a positive number (got " + G4(o.alpha) + "): Theorem 1's alpha";
  }
  if (!(std::isfinite(o.beta) && o.beta > 0.0)) {
    return "--beta must be a positive number (got " + G4(o.beta) + "): Theorem 1's beta";
  }
  // 1e6, as the gains: the theorems' matrices square it, and beyond 1e150 they overflow.
  if (o.rho0 && !(std::isfinite(*o.rho0) && *o.rho0 >= 0.0 && *o.rho0 <= 1e6)) {
    return "--rho0 must be a number in [0, 1e6] (got " + G4(*o.rho0) +
           "): the Lipschitz constant of the uncertain factor";
  }
  if (!(std::isfinite(o.safety) && o.safety >= 1.0)) {
    return "--safety must be a number >= 1 (got " + G4(o.safety) +
           "): the required margin is safety x h";
  }
  if (!(std::isfinite(o.tune_horizon_s) && o.tune_horizon_s > 0.0)) {
    return "--tune-horizon must be a positive number of seconds (got " + G4(o.tune_horizon_s) + ")";
  }
  if (o.empirical_duration_s != -1.0 &&
      !(std::isfinite(o.empirical_duration_s) && o.empirical_duration_s > 0.0)) {
    return "--empirical-duration must be a positive number of seconds (got " +
           G4(o.empirical_duration_s) + ")";
  }
  return "";
}

void Progress(const DesignRequest& q, const std::string& what) {
  if (q.progress) q.progress(what);
}

void DescribeDelaysAndFactor(const Scenario& s, const DesignRequest& q, DesignReport* r);

/// b joined into a, as theory::DelayBoundsOf joins the links of one topology.
void JoinDelayBounds(const theory::DelayBounds& b, theory::DelayBounds* a) {
  a->constant = a->constant && b.constant && b.h_s == a->h_s;
  a->h_s = std::max(a->h_s, b.h_s);
  if (!b.kappa || !a->kappa) {
    a->kappa.reset();
  } else {
    a->kappa = std::max(*a->kappa, *b.kappa);
  }
  a->time_varying = a->time_varying || b.time_varying;
}

/// The delay models other than channel event e's own that may be in force on e's links
/// just before or after time t: each such link's own (its [[channel.link]] override, else
/// the default) and those of the other channel events whose window holds t on a link of e.
std::vector<const DelayConfig*> ModelsAround(const Scenario& s, const ScenarioEvent& e, double t) {
  using LinkPair = std::pair<int, int>;
  const auto lists = [](const std::vector<LinkPair>& links, int from, int to) {
    return links.empty() || std::find(links.begin(), links.end(), LinkPair{from, to}) != links.end();
  };
  std::vector<const DelayConfig*> models;
  bool default_used = false;
  const std::vector<LinkPair> all = UnionTopology(s).Links();
  for (const auto& [from, to] : all) {
    if (!lists(e.links, from, to)) continue;
    const auto o = std::find_if(s.links.begin(), s.links.end(), [&](const LinkOverride& l) {
      return l.from == from && l.to == to && l.delay;
    });
    if (o != s.links.end()) {
      models.push_back(&*o->delay);
    } else {
      default_used = true;
    }
  }
  if (default_used) models.push_back(&s.delay);
  for (const ScenarioEvent& x : s.events) {
    if (&x == &e || x.kind != EventKind::kChannel || !x.delay || t < x.at_s || t > x.until_s) continue;
    const bool meets = std::any_of(all.begin(), all.end(), [&](const LinkPair& l) {
      return lists(e.links, l.first, l.second) && lists(x.links, l.first, l.second);
    });
    if (meets) models.push_back(&*x.delay);
  }
  return models;
}

/// The delay bounds over the whole timeline: every link of every topology (each with
/// its default or per-link model) and every delay a channel event gives. Without events
/// exactly theory::DelayBoundsOf(s). *jumps_up_out: whether an event's edge makes tau jump up.
theory::DelayBounds TimelineDelayBounds(const Scenario& s, bool* jumps_up_out = nullptr) {
  if (jumps_up_out) *jumps_up_out = false;
  if (s.events.empty()) return theory::DelayBoundsOf(s);
  Scenario u = s;
  u.edges.clear();
  u.leader_links.clear();
  for (const auto& [from, to] : UnionTopology(s).Links()) {
    if (from == 0) {
      u.leader_links.push_back(to);
    } else {
      u.edges.emplace_back(to, from);
    }
  }
  theory::DelayBounds d = theory::DelayBoundsOf(u);
  bool jumps_up = false;
  for (const ScenarioEvent& e : s.events) {
    if (e.kind != EventKind::kChannel || !e.delay) continue;
    JoinDelayBounds(theory::DelayBoundsOf(*e.delay), &d);
    // tau jumps up where the event's delay takes over from a smaller one, or hands back
    // to a larger one: there tau' is unbounded, whatever each model's own rate. Not at
    // t = 0 (nothing to take over from) nor at or after the run's end.
    if (e.at_s > 0.0) {
      for (const DelayConfig* m : ModelsAround(s, e, e.at_s)) {
        jumps_up = jumps_up || NominalDelaySeconds(*e.delay, e.at_s) > NominalDelaySeconds(*m, e.at_s);
      }
    }
    if (e.until_s < s.duration_s) {
      for (const DelayConfig* m : ModelsAround(s, e, e.until_s)) {
        jumps_up = jumps_up || NominalDelaySeconds(*m, e.until_s) > NominalDelaySeconds(*e.delay, e.until_s);
      }
    }
  }
  if (jumps_up) {
    d.kappa.reset();
    d.time_varying = true;
    d.constant = false;
  }
  if (jumps_up_out) *jumps_up_out = jumps_up;
  return d;
}

/// What leaves the delay's rate unbounded: each kind of delay model of the scenario (the
/// default, per-link, channel events') that has no bounded rate, and an event's upward jump.
std::string DelayRateUnboundedWhy(const Scenario& s, bool jumps_up) {
  std::vector<const DelayConfig*> models = {&s.delay};
  for (const LinkOverride& l : s.links) {
    if (l.delay) models.push_back(&*l.delay);
  }
  for (const ScenarioEvent& e : s.events) {
    if (e.kind == EventKind::kChannel && e.delay) models.push_back(&*e.delay);
  }
  bool uniform = false, acoustic = false, trace = false;
  for (const DelayConfig* m : models) {
    if (theory::DelayBoundsOf(*m).kappa) continue;
    uniform = uniform || m->kind == DelayKind::kUniform;
    acoustic = acoustic || m->kind == DelayKind::kAcoustic;
    trace = trace || m->kind == DelayKind::kTrace;
  }
  std::vector<std::string> why;
  if (uniform) why.push_back("uniform jitter draws a new delay per message");
  if (acoustic) why.push_back("an acoustic delay follows the range, whose rate nothing bounds");
  if (trace) why.push_back("a trace's delay changes as its series does, at no bounded rate");
  if (jumps_up) why.push_back("a channel event makes tau jump up, at its start or its end");
  if (why.empty()) why.push_back("no model bounds it");
  std::string text;
  for (std::size_t k = 0; k < why.size(); ++k) text += (k ? "; " : "") + why[k];
  return text;
}

/// Gains, topology, delays and the uncertain factor: the data every result below uses.
void DescribeProblem(const Scenario& s, const DesignRequest& q, DesignReport* r) {
  r->scenario_name = s.name;
  r->followers = s.followers;
  r->k1 = q.k1.value_or(s.k1);
  r->k2 = q.k2.value_or(s.k2);
  r->alpha = q.alpha;
  r->beta = q.beta;
  r->gains_from_flags = q.k1.has_value() || q.k2.has_value();
  r->safety = q.safety;
  r->duration_s = s.duration_s;
  r->period_s = ToSeconds(s.period_us());
  r->position_tol_m = s.metrics.position_tol_m;
  r->velocity_tol_mps = s.metrics.velocity_tol_mps;

  const Topology topo = Topology::Build(s.followers, s.edges, s.leader_links);
  r->H = topo.H();
  r->eigenvalues = theory::HEigenvalues(r->H);
  r->unreachable_followers = topo.UnreachableFollowers();
  DescribeDelaysAndFactor(s, q, r);
}

/// The delay bounds and the uncertain factor (cheap: no matrix of the topology).
void DescribeDelaysAndFactor(const Scenario& s, const DesignRequest& q, DesignReport* r) {
  // Delays: the scenario's, or h (and kappa) from the flags describing one common delay.
  r->delay_model = s.delay.kind;
  r->per_link_overrides = !s.links.empty();
  bool jumps_up = false;
  r->delay = TimelineDelayBounds(s, &jumps_up);
  r->delay_rate_unbounded_why = r->delay.kappa ? "" : DelayRateUnboundedWhy(s, jumps_up);
  r->delay_from_flags = q.h_s.has_value() || q.kappa.has_value();
  if (q.h_s) r->delay.h_s = *q.h_s;
  if (q.kappa) r->delay.kappa = *q.kappa;
  if (r->delay_from_flags) {
    r->delay.time_varying = !r->delay.kappa || *r->delay.kappa > 0.0;
    r->delay.constant = !r->delay.time_varying;
  }

  r->disturbance = s.disturbance.kind;
  r->relative_to_leader = s.disturbance.relative_to_leader;
  r->lipschitz = theory::LipschitzOf(s.disturbance);
  r->rho0_from_flag = q.rho0.has_value();
  if (q.rho0) {
    r->rho0 = *q.rho0;
  } else if (r->lipschitz.applicable || s.disturbance.kind == DisturbanceKind::kPaperExample2) {
    r->rho0 = r->lipschitz.rho0;
  }
  if (s.disturbance.kind != DisturbanceKind::kNone) {
    r->factor = r->lipschitz.applicable ? FactorKind::kLipschitz : FactorKind::kUncovered;
  }
  // --rho0 states an assumed Lipschitz bound for the factor (or, with none, adds one). An
  // absolute factor (relative_to_leader = false) does not vanish at consensus: no bound
  // makes it the F_i of the error system, so it stays not covered.
  const bool absolute = s.disturbance.kind == DisturbanceKind::kPaperExample2 &&
                        !s.disturbance.relative_to_leader;
  if (q.rho0 && *q.rho0 > 0.0 && !absolute) r->factor = FactorKind::kLipschitz;
}

/// Why Theorem 3 does not apply, or "" when it does.
std::string Theorem3NotApplicable(const DesignReport& r) {
  const std::optional<double>& kappa = r.delay.kappa;
  if (!kappa) return "the delay's rate is unbounded (" + r.delay_rate_unbounded_why + ")";
  if (*kappa >= 1.0) return "kappa = " + G4(*kappa) + " >= 1 (Assumption 3 needs tau' <= kappa < 1)";
  if (r.factor != FactorKind::kUncovered) return "";
  return r.disturbance == DisturbanceKind::kOceanCurrent
             ? "the ocean current has no Lipschitz bound of the form f(x_i) - f(x_0) "
               "(pass --rho0 to assume one)"
             : "the uncertain factor is not of the form f(x_i) - f(x_0) that Theorem 3 "
               "covers (relative_to_leader = false: it does not vanish at consensus, and no "
               "--rho0 makes it so)";
}

/// Theorem 3 (LMI (27)-(28), every multiplier free, CSDP) at the gains and delay bounds:
/// feasibility at (h, kappa), max_delay_s by bisection, the paper's multipliers.
void RunTheorem3(const DesignRequest& q, DesignReport* r) {
  Theorem3Section& t = r->theorem3;
  t.not_evaluated_reason = Theorem3NotApplicable(*r);
  if (!t.not_evaluated_reason.empty()) return;
  t.evaluated = true;
  t.rho0_from_flag = q.rho0.has_value();
  t.input.H = r->H;
  t.input.k1 = r->k1;
  t.input.k2 = r->k2;
  t.input.h_s = r->delay.h_s;
  t.input.kappa = *r->delay.kappa;
  if (q.rho0) {  // an assumed bound ||F|| <= rho0 (||x|| + ||v||): G = J = rho0 I
    t.input.lambda_G2 = t.input.lambda_J2 = *q.rho0 * *q.rho0;
  } else {
    t.input.lambda_G2 = r->lipschitz.lambda_max_G2;
    t.input.lambda_J2 = r->lipschitz.lambda_max_J2;
  }
  t.at_h = CheckTheorem3(t.input);
  t.max_delay = MaxDelayTheorem3(t.input);
  t.paper = PaperMultipliersMaxEigenvalue(t.input);
}

void RunEmpirical(const Scenario& s, const DesignRequest& q, DesignReport* r) {
  EmpiricalMarginOptions eo;
  eo.duration_s = q.empirical_duration_s;
  eo.initial_upper_s = r->margin.stable_at_zero ? 2.0 * r->margin.tau_s : 1.0;
  Progress(q, "empirical margin (bisection over shoal sim runs)...");
  const auto t0 = std::chrono::steady_clock::now();
  EmpiricalSection e;
  e.margin = FindEmpiricalMargin(s, eo);
  e.wall_s = WallSince(t0);
  e.model = EmpiricalModelDescription(s, e.margin.duration_s);
  r->empirical = std::move(e);
}

double FactorMarginOf(const DesignReport& r, double k1, double k2) {
  const theory::FactorDelayMargin f =
      theory::ComputeFactorDelayMargin(r.eigenvalues, k1, k2, r.lipschitz);
  return f.stable_at_zero ? f.tau_s : 0.0;
}

void RunTune(const Scenario& s, const DesignRequest& q, DesignReport* r) {
  TuneOptions to;
  to.safety = q.safety;
  to.horizon_s = q.tune_horizon_s;
  to.cost = q.tune_cost;
  Progress(q, "tuning k1, k2 with Ceres (4 starts)...");
  const auto t0 = std::chrono::steady_clock::now();
  TuneSection t;
  t.cost = q.tune_cost;
  t.result = Tune(s, r->eigenvalues, r->delay.h_s, to);
  t.wall_s = WallSince(t0);
  t.before_factor_margin_s = FactorMarginOf(*r, t.result.before.k1, t.result.before.k2);
  if (t.result.ok) {
    t.after_factor_margin_s = FactorMarginOf(*r, t.result.after.k1, t.result.after.k2);
  }
  r->tune = std::move(t);
}

void RunAdvice(const DesignRequest& q, DesignReport* r) {
  AdviceSection a;
  if (!r->theorem3.evaluated) {
    a.not_evaluated_reason = "Theorem 3 does not apply: " + r->theorem3.not_evaluated_reason;
  } else if (!r->theorem3.input.IsValid(&a.not_evaluated_reason)) {
    a.not_evaluated_reason = "Theorem 3's input is invalid: " + a.not_evaluated_reason;
  } else {
    Progress(q, "advising gains (Theorem 3 over scales of the gains)...");
    AdviceInput in;
    in.theorem3 = r->theorem3.input;
    in.eigenvalues = r->eigenvalues;
    in.lipschitz = r->lipschitz;
    in.factor_slopes_known = r->factor_margin_shown;
    a.evaluated = true;
    a.advice = AdviseGains(in);
  }
  r->advice = std::move(a);
}

void Decide(DesignReport* r) {
  VerdictInput vi;
  vi.k1 = r->k1;
  vi.k2 = r->k2;
  vi.h_s = r->delay.h_s;
  vi.period_s = r->period_s;
  vi.kappa = r->delay.kappa;
  vi.kappa_unbounded_why = r->delay_rate_unbounded_why;
  vi.delay_time_varying = r->delay.time_varying;
  vi.delay_common_constant = r->delay.constant;
  vi.factor = r->factor;
  vi.rho0 = r->rho0.value_or(0.0);
  vi.theorem1 = r->theorem1 ? &*r->theorem1 : nullptr;
  vi.theorem2 = r->theorem2 ? &*r->theorem2 : nullptr;
  vi.margin = &r->margin;
  vi.factor_margin = r->factor_margin_shown ? &r->factor_margin : nullptr;
  vi.safety = r->safety;
  if (r->theorem3.evaluated) {
    const Theorem3Section& t = r->theorem3;
    vi.theorem3_certified = t.at_h.certifies();
    if (t.max_delay.input_valid) {
      vi.theorem3_max_delay_s = t.max_delay.feasible_at_zero ? t.max_delay.max_delay_s : 0.0;
    }
  }
  r->verdict = design::Decide(vi);
}

}  // namespace

bool DesignRequest::IsValid(const Scenario& s, std::string* why) const {
  std::string e = ValueError(*this);
  const theory::Lipschitz lip = theory::LipschitzOf(s.disturbance);
  if (e.empty() && rho0 && lip.applicable && s.disturbance.kind != DisturbanceKind::kNone &&
      *rho0 < lip.rho0) {
    e = "--rho0 " + G4(*rho0) + " is below the uncertain factor's own Lipschitz constant " +
        G4(lip.rho0) + " (" + DisturbanceName(s.disturbance.kind) +
        "): a certificate would rest on a bound the model does not satisfy; give --rho0 >= " +
        G4(lip.rho0) + " or leave it out";
  }
  // A current that can flow is a factor no bound of zero covers: rho0 = 0 would certify
  // the formation as if the water stood still.
  if (e.empty() && rho0 && *rho0 == 0.0 && s.disturbance.kind == DisturbanceKind::kOceanCurrent &&
      s.disturbance.current.max_speed_mps > 0.0) {
    e = "--rho0 0 says there is no uncertain factor, but the scenario's ocean current flows at up "
        "to " + G4(s.disturbance.current.max_speed_mps) +
        " m/s: give --rho0 > 0 to assume a bound for it, or leave --rho0 out";
  }
  if (why) *why = e;
  return e.empty();
}

const Theorem3Result& Theorem3Section::CertificateResult() const {
  return at_h.certifies() || !max_delay.feasible_at_zero ? at_h : max_delay.at_max;
}

// Theorem 3 at h and its bisection: the whole of `shoal design` measured on a 2-vCPU AMD
// EPYC VM, shared, 2026-12-01 (docs/benchmarks.md), chains (n - 1 edges) and dense
// swarms (every follower hears every other), seconds [peak memory]:
//   n        5           8            10           12           15
//   chain    0.7-1.0     1.3          2.9-4.2      11.6 [97 MB]  34.4 [137 MB]
//   dense    0.2-0.3     3.5          13.3-14.0    50.4 [97 MB]
// (chain 20 ran past 300 s.) Fitted as n^4 (a n^2 + b links), links = edges + leader
// links, within 25 % from n = 8 on; memory as the Schur complement plus the process.
// Those scenarios (Example 2's delay and factor) were infeasible beyond h = 0.1 s, so
// their bisection stopped at its first step: about two solves. A feasible LMI bisects to
// 1 ms, 14 solves or more (a chain of 10 with a constant delay: 14 solves, 58 s), and
// which it is shows only once solved: the estimate is the worst, kWorstOverFit times the
// fit. 10 min is then reached at about 17 chained or 13 dense followers.
constexpr double kSecondsPerN6 = 2.6e-6;
constexpr double kSecondsPerN4Link = 1.55e-5;
constexpr double kWorstOverFit = 8.0;
constexpr double kBaseBytes = 64.0 * (1 << 20);  // the process without the SDP
constexpr double kSchurBytesPerEntry = 8.8;      // the dense m x m matrix and CSDP's extras

DesignEstimate EstimateDesign(const Scenario& s, const DesignRequest& q) {
  DesignEstimate e;
  DesignReport r;
  DescribeDelaysAndFactor(s, q, &r);
  e.theorem3 = Theorem3NotApplicable(r).empty();
  if (!e.theorem3) return e;
  const double n = s.followers;
  const double links = static_cast<double>(s.edges.size() + s.leader_links.size());
  const double m = 12.0 * n * n + 5.0 * n;
  e.lmi_variables = static_cast<std::int64_t>(m);
  e.wall_seconds =
      kWorstOverFit * n * n * n * n * (kSecondsPerN6 * n * n + kSecondsPerN4Link * links);
  e.memory_bytes = kBaseBytes + kSchurBytesPerEntry * m * m;
  return e;
}

std::string LargeDesignRefusal(const Scenario& s, const DesignRequest& q) {
  if (q.empirical) {
    // The search runs shoal sim a dozen times or more: one run too large for shoal sim
    // is too large for it.
    const std::string run = LargeRunRefusal(s, q.empirical_duration_s, RunPace::kSim,
                                            "--empirical-duration (or run.duration_s)");
    if (!run.empty()) return "--empirical: each of its runs is large: " + run;
  }
  const DesignEstimate e = EstimateDesign(s, q);
  if (!e.large()) return "";
  char text[320];
  std::snprintf(text, sizeof(text),
                "refusing a large design (Theorem 3's LMI for %d followers and %zu links: "
                "%lld variables, about %.3g h and %.3g GiB of memory; the limits are 10 min "
                "and 4 GiB); use fewer followers, or pass --allow-large to run it anyway",
                s.followers, s.edges.size() + s.leader_links.size(),
                static_cast<long long>(e.lmi_variables), e.wall_seconds / 3600.0,
                e.memory_bytes / (1 << 30));
  return text;
}

DesignReport BuildDesignReport(const Scenario& scenario, const DesignRequest& q) {
  DesignReport r;
  DescribeProblem(scenario, q, &r);
  Scenario s = scenario;  // the empirical margin and the tuner run these gains
  s.k1 = r.k1;
  s.k2 = r.k2;
  r.theorem1 = theory::ComputeTheorem1(r.H, r.k1, r.k2, r.alpha, r.beta);
  if (r.theorem1 && r.rho0) {
    r.theorem2 = theory::ComputeTheorem2(*r.theorem1, r.alpha, r.beta, *r.rho0);
  }
  RunTheorem3(q, &r);
  r.margin = theory::ComputeDelayMargin(r.eigenvalues, r.k1, r.k2);
  r.factor_margin_shown = r.disturbance != DisturbanceKind::kNone && r.lipschitz.slopes_known;
  r.factor_margin = theory::ComputeFactorDelayMargin(r.eigenvalues, r.k1, r.k2, r.lipschitz);
  if (Timeline(scenario).switches_topology()) {
    r.switching = AnalyseSwitching(scenario, r.k1, r.k2, r.alpha, r.beta);
  }
  if (const FormationDelay f = FormationAcousticDelay(scenario); f.applicable) {
    r.formation_delay = f;
  }
  if (q.empirical) RunEmpirical(s, q, &r);
  if (q.tune) RunTune(s, q, &r);
  if (q.advise) RunAdvice(q, &r);
  Decide(&r);
  if (r.switching) r.verdict = SwitchingVerdict(*r.switching, r.delay.h_s, r.factor);
  return r;
}

double DesignReport::GoverningMarginS() const {
  if (switching) return switching->min_margin_s;
  return margin.stable_at_zero ? margin.tau_s : 0.0;
}

const char* DelayKindName(DelayKind k) {
  switch (k) {
    case DelayKind::kNone:
      return "none";
    case DelayKind::kConstant:
      return "constant";
    case DelayKind::kSinusoid:
      return "sinusoid";
    case DelayKind::kUniform:
      return "uniform";
    case DelayKind::kAcoustic:
      return "acoustic";
    case DelayKind::kTrace:
      return "trace";
  }
  return "?";
}

const char* DisturbanceName(DisturbanceKind k) {
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

}  // namespace design
}  // namespace shoal

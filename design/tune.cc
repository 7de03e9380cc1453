#include "design/tune.h"

#include <ceres/ceres.h>
#include <glog/logging.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "design/sim_eval.h"

namespace shoal {
namespace design {
namespace {

/// Margin theta(r) of (k1, k2) = (r, 1); 0 if unstable without delay.
double ShapeMargin(const std::vector<theory::Complex>& ev, double r) {
  const theory::DelayMargin d = theory::ComputeDelayMargin(ev, r, 1.0);
  return d.stable_at_zero ? d.tau_s : 0.0;
}

struct Gains {
  double k1 = 0.0, k2 = 0.0;
  bool valid = false;
};

Gains GainsOf(const std::vector<theory::Complex>& ev, double log_r, double u, double required_s) {
  Gains g;
  const double r = std::exp(log_r);
  const double theta = ShapeMargin(ev, r);
  if (!(theta > 0.0) || !(u > 0.0)) return g;
  g.k2 = u * theta / required_s;
  g.k1 = r * g.k2 * g.k2;
  g.valid = std::isfinite(g.k1) && std::isfinite(g.k2) && g.k1 > 0.0 && g.k2 > 0.0;
  return g;
}

/// Residuals sqrt(period) e_p,i(t_k) of a run with the gains of (log r, u).
struct SimResiduals {
  const Scenario* s;
  const std::vector<theory::Complex>* ev;
  double required_s;
  double horizon_s;
  CostKind cost;
  std::size_t count;
  int* runs;

  bool operator()(double const* const* p, double* residuals) const {
    const Gains g = GainsOf(*ev, p[0][0], p[0][1], required_s);
    if (!g.valid) return false;
    std::vector<double> r;
    ++*runs;
    const SimOutcome o = RunSwarm(WithGains(*s, g.k1, g.k2), horizon_s, cost, &r);
    // A run that diverged stops early: no cost for it (Ceres rejects the step).
    if (o.diverged_id != 0 || r.size() != count) return false;
    for (std::size_t i = 0; i < count; ++i) {
      if (!std::isfinite(r[i])) return false;
      residuals[i] = r[i];
    }
    return true;
  }
};

/// The numbers reported for a pair of gains: margin, cost over the horizon, and the
/// convergence of a full-length run.
TunePoint Measure(const Scenario& s, const std::vector<theory::Complex>& ev, double k1, double k2,
                  double horizon_s, CostKind cost, int* sim_runs) {
  TunePoint t;
  t.k1 = k1;
  t.k2 = k2;
  const theory::DelayMargin d = theory::ComputeDelayMargin(ev, k1, k2);
  t.margin_s = d.tau_s;
  const Scenario g = WithGains(s, k1, k2);
  ++*sim_runs;
  const SimOutcome o = RunSwarm(g, horizon_s, cost);
  t.cost = o.cost;
  t.position_ise_m2s = o.ise_m2s;
  ++*sim_runs;
  const SimOutcome full = RunSwarm(g, -1.0);
  t.converged = full.converged;
  t.convergence_time_s = full.convergence_time_s;
  return t;
}

/// The search box of (log r, u).
struct Box {
  double log_r_lo, log_r_hi;
  double u_lo = 0.02, u_hi = 1.0;
};

/// Starts: the scenario's gains (scaled down onto the feasible set if they miss the
/// requirement), shapes 4x either side of the scenario's near the margin bound, and the
/// scenario's shape on the bound.
std::vector<std::pair<double, double>> Starts(const Scenario& s,
                                              const std::vector<theory::Complex>& ev,
                                              double required_s, Box* box) {
  const double r0 = s.k1 / (s.k2 * s.k2);
  const double theta0 = ShapeMargin(ev, r0);
  const double u0 = theta0 > 0.0 ? std::min(1.0, s.k2 * required_s / theta0) : 0.5;
  const double log_r0 = std::log(r0);
  box->log_r_lo = log_r0 - std::log(100.0);
  box->log_r_hi = log_r0 + std::log(100.0);
  return {{log_r0, u0}, {log_r0 - std::log(4.0), 0.9}, {log_r0 + std::log(4.0), 0.9}, {log_r0, 1.0}};
}

/// Levenberg-Marquardt from (log r, u) = x over the box; fills the start's outcome.
void SolveFrom(SimResiduals* functor, double x[2], const Box& box, int max_iterations,
               TuneStart* ts) {
  ceres::NumericDiffOptions nd;
  nd.relative_step_size = 1e-3;
  auto* cost = new ceres::DynamicNumericDiffCostFunction<SimResiduals, ceres::FORWARD>(
      functor, ceres::TAKE_OWNERSHIP, nd);
  cost->AddParameterBlock(2);
  cost->SetNumResiduals(static_cast<int>(functor->count));
  ceres::Problem problem;
  problem.AddResidualBlock(cost, nullptr, x);
  problem.SetParameterLowerBound(x, 0, box.log_r_lo);
  problem.SetParameterUpperBound(x, 0, box.log_r_hi);
  problem.SetParameterLowerBound(x, 1, box.u_lo);
  problem.SetParameterUpperBound(x, 1, box.u_hi);
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = max_iterations;
  // The cost is known to ~1e-4 relative at best across starts; finer tolerances only
  // spend simulations.
  so.function_tolerance = 1e-4;
  so.parameter_tolerance = 1e-4;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  ts->iterations = static_cast<int>(summary.iterations.size());
  ts->message = summary.message;
  ts->usable = summary.IsSolutionUsable() && std::isfinite(summary.final_cost);
  ts->cost = 2.0 * summary.final_cost;  // Ceres' cost is half the sum of squares
}

/// One start of the multi-start search.
TuneStart RunStart(const SimResiduals& proto, double lr, double u, const Box& box,
                   int max_iterations) {
  TuneStart ts;
  const Gains g0 = GainsOf(*proto.ev, lr, u, proto.required_s);
  ts.k1_start = g0.k1;
  ts.k2_start = g0.k2;
  double x[2] = {lr, std::clamp(u, box.u_lo, box.u_hi)};
  if (!g0.valid) {
    ts.message = "start not usable: this shape is unstable without delay";
    return ts;
  }
  auto* functor = new SimResiduals(proto);
  {
    // Ceres cannot start from a point it cannot evaluate (a run that diverges).
    std::vector<double> r0(proto.count);
    const double* p0[] = {x};
    if (!(*functor)(p0, r0.data())) {
      delete functor;
      ts.message = "start not usable: the run diverges";
      return ts;
    }
  }
  SolveFrom(functor, x, box, max_iterations, &ts);
  const Gains g = GainsOf(*proto.ev, x[0], x[1], proto.required_s);
  ts.k1 = g.k1;
  ts.k2 = g.k2;
  ts.usable = ts.usable && g.valid;
  return ts;
}

}  // namespace

TuneResult Tune(const Scenario& s, const std::vector<theory::Complex>& ev, double h_s,
                const TuneOptions& opt) {
  TuneResult out;
  out.h_s = h_s;
  out.horizon_s = std::min(opt.horizon_s, s.duration_s);
  const double period_s = ToSeconds(s.period_us());
  // The step semantics delay every message by at least one control period, so even a
  // delay-free scenario is protected for that much.
  out.required_margin_s = opt.safety * std::max(h_s, period_s);
  out.before = Measure(s, ev, s.k1, s.k2, out.horizon_s, opt.cost, &out.sim_runs);
  out.before_feasible = out.before.margin_s >= out.required_margin_s;

  // Number of residuals of a complete run over the horizon: ticks 0..final (Swarm) per
  // follower.
  const auto ticks = static_cast<std::size_t>(s.final_tick(out.horizon_s)) + 1;
  const std::size_t count = 2 * ticks * static_cast<std::size_t>(s.followers);
  const SimResiduals proto{&s,       &ev,   out.required_margin_s, out.horizon_s,
                           opt.cost, count, &out.sim_runs};
  Box box;
  const std::vector<std::pair<double, double>> starts =
      Starts(s, ev, out.required_margin_s, &box);

  // Ceres' termination message is reported with each start; glog's copy of it on stderr
  // would only duplicate it (and warn about InitGoogleLogging): silence glog meanwhile.
  const int old_minloglevel = FLAGS_minloglevel;
  FLAGS_minloglevel = google::GLOG_FATAL;
  int best = -1;
  for (const auto& [lr, u] : starts) {
    out.starts.push_back(RunStart(proto, lr, u, box, opt.max_iterations));
    const TuneStart& ts = out.starts.back();
    if (ts.usable && (best < 0 || ts.cost < out.starts[best].cost)) {
      best = static_cast<int>(out.starts.size()) - 1;
    }
  }
  FLAGS_minloglevel = old_minloglevel;
  if (best < 0) {
    out.message = "no start gave a usable solution";
    return out;
  }
  out.after = Measure(s, ev, out.starts[best].k1, out.starts[best].k2, out.horizon_s, opt.cost,
                      &out.sim_runs);
  out.ok = true;
  return out;
}

}  // namespace design
}  // namespace shoal

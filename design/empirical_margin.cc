#include "design/empirical_margin.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>

#include "design/sim_eval.h"

namespace shoal {
namespace design {

EmpiricalMargin FindEmpiricalMargin(const Scenario& s, const EmpiricalMarginOptions& opt) {
  EmpiricalMargin r;
  const Micros period_us = s.period_us();
  r.period_s = ToSeconds(period_us);
  r.duration_s = opt.duration_s > 0 ? opt.duration_s : s.duration_s;

  auto converges = [&](std::int64_t ticks) {
    ++r.runs;
    const double tau = ToSeconds(ticks * period_us);
    return RunSwarm(WithConstantDelay(s, tau), r.duration_s).converged;
  };

  // A neighbour whose newest message is older than the timeout drops out of the law:
  // beyond that the loop is a different one, so the search stays below it.
  const std::int64_t cap = std::max<std::int64_t>(
      1, static_cast<std::int64_t>(
             std::floor((s.neighbour_timeout_s - r.period_s) / r.period_s + 1e-9)));
  r.cap_s = ToSeconds(cap * period_us);

  // One period is the smallest delay the step semantics allow (tau = 0 behaves the same).
  if (!converges(1)) {
    r.converges_without_delay = false;
    r.margin_s = 0.0;
    r.first_failing_s = r.period_s;
    return r;
  }
  r.converges_without_delay = true;

  std::int64_t lo = 1;  // converges
  std::int64_t hi = std::clamp<std::int64_t>(
      static_cast<std::int64_t>(std::ceil(opt.initial_upper_s / r.period_s)), 2, cap);
  // Grow the bracket until a failing delay is found or the cap is reached.
  while (converges(hi)) {
    lo = hi;
    if (hi == cap) {
      r.capped = true;
      r.margin_s = ToSeconds(cap * period_us);
      r.first_failing_s = r.margin_s;
      return r;
    }
    hi = std::min(cap, 2 * hi);
  }
  // Bisection over whole periods: lo converges, hi does not.
  while (hi - lo > 1) {
    const std::int64_t mid = lo + (hi - lo) / 2;
    if (converges(mid)) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  r.margin_s = ToSeconds(lo * period_us);
  r.first_failing_s = ToSeconds(hi * period_us);
  return r;
}

std::string EmpiricalModelDescription(const Scenario& s, double duration_s) {
  std::ostringstream o;
  o << "shoal sim's model (nonlinear Fossen 5-DOF REMUS plant, feedback linearisation with "
       "the scenario's actuator limits, protocol (10) with offsets, the scenario's leader path, ";
  switch (s.disturbance.kind) {
    case DisturbanceKind::kNone:
      o << "no uncertain factor";
      break;
    case DisturbanceKind::kPaperExample2:
      o << "paper Example 2's uncertain factor at the delayed arguments";
      break;
    case DisturbanceKind::kOceanCurrent:
      o << "the Gauss-Markov ocean current";
      break;
  }
  o << ", losses as configured) with one constant delay on every link, resolved to whole "
       "control periods; converged = shoal sim's criterion at the end of a "
    << duration_s << " s run";
  return o.str();
}

}  // namespace design
}  // namespace shoal

#include "design/sim_eval.h"

#include <algorithm>
#include <cmath>

#include "core/swarm.h"

namespace shoal {
namespace design {

const char* CostName(CostKind k) {
  switch (k) {
    case CostKind::kPositionIse:
      return "position_ise";
    case CostKind::kIse:
      return "ise";
    case CostKind::kItse:
      return "itse";
  }
  return "?";
}

SimOutcome RunSwarm(const Scenario& s, double duration_s, CostKind cost,
                    std::vector<double>* residuals) {
  Swarm swarm(s, duration_s);
  const double period_s = ToSeconds(swarm.period_us());
  const double sqrt_period = std::sqrt(period_s);
  if (residuals) {
    residuals->clear();
    residuals->reserve(2 * static_cast<std::size_t>(swarm.final_tick() + 1) *
                       static_cast<std::size_t>(s.followers));
  }
  const double wp = cost == CostKind::kPositionIse ? 1.0 : 1.0 / s.metrics.position_tol_m;
  const double wv = cost == CostKind::kPositionIse ? 0.0 : 1.0 / s.metrics.velocity_tol_mps;
  SimOutcome out;
  bool more = true;
  while (more) {
    more = swarm.Step(nullptr);
    if (swarm.metrics().samples() == 0) break;
    // Residual weight: sqrt(dt), times sqrt(t) for the time-weighted cost.
    const double w = cost == CostKind::kItse
                         ? sqrt_period * std::sqrt(swarm.metrics().last_time_s())
                         : sqrt_period;
    for (const FormationErrors& e : swarm.metrics().final_errors()) {
      const double rp = w * wp * e.position_m, rv = w * wv * e.velocity_mps;
      out.ise_m2s += e.position_m * e.position_m * period_s;
      out.cost += rp * rp + rv * rv;
      if (residuals) {
        residuals->push_back(rp);
        residuals->push_back(rv);
      }
    }
  }
  out.diverged_id = swarm.diverged_id();
  out.sim_time_s = swarm.sim_time_s();
  out.converged = swarm.metrics().converged() && out.diverged_id == 0;
  out.convergence_time_s = out.converged ? swarm.metrics().convergence_time_s() : -1.0;
  return out;
}

Scenario WithConstantDelay(const Scenario& s, double tau_s) {
  Scenario c = s;
  c.delay = DelayConfig{DelayKind::kConstant, tau_s, 0.0, 0.0};
  for (LinkOverride& o : c.links) o.delay.reset();
  // A channel event's delay would take over from the constant one: it goes too (an
  // event that changed only the delay goes whole; one with a loss keeps its loss).
  for (ScenarioEvent& e : c.events) {
    if (e.kind == EventKind::kChannel) e.delay.reset();
  }
  c.events.erase(std::remove_if(c.events.begin(), c.events.end(),
                                [](const ScenarioEvent& e) {
                                  return e.kind == EventKind::kChannel && !e.delay && !e.loss;
                                }),
                 c.events.end());
  return c;
}

Scenario WithGains(const Scenario& s, double k1, double k2) {
  Scenario c = s;
  c.k1 = k1;
  c.k2 = k2;
  return c;
}

}  // namespace design
}  // namespace shoal

#include "design/sim_eval.h"

#include <cmath>

#include "core/swarm.h"

namespace shoal {
namespace design {

SimOutcome RunSwarm(const Scenario& s, double duration_s, std::vector<double>* residuals) {
  Swarm swarm(s, duration_s);
  const double period_s = ToSeconds(swarm.period_us());
  const double sqrt_period = std::sqrt(period_s);
  if (residuals) {
    residuals->clear();
    residuals->reserve(2 * static_cast<std::size_t>(swarm.final_tick() + 1) *
                       static_cast<std::size_t>(s.followers));
  }
  SimOutcome out;
  bool more = true;
  while (more) {
    more = swarm.Step(nullptr);
    if (swarm.metrics().samples() == 0) break;
    for (const FormationErrors& e : swarm.metrics().final_errors()) {
      const double p = e.position_m / s.metrics.position_tol_m;
      const double v = e.velocity_mps / s.metrics.velocity_tol_mps;
      out.ise_m2s += e.position_m * e.position_m * period_s;
      out.cost_s += (p * p + v * v) * period_s;
      if (residuals) {
        residuals->push_back(sqrt_period * p);
        residuals->push_back(sqrt_period * v);
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

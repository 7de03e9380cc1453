// Accuracy of the RK4 internal step: runs a scenario with integrator steps of 20, 10, 5
// and 1 ms and prints the convergence time and the largest follower position difference
// to the 20 ms run.   Usage: build/bench/integrator_accuracy SCENARIO DURATION_S
#include <cstdio>
#include <cstdlib>
#include <exception>

#include "core/swarm.h"
#include "scenario/loader.h"

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s SCENARIO DURATION_S\n", argv[0]);
    return 2;
  }
  try {
    const shoal::Scenario ref = shoal::LoadScenario(argv[1]);
    const double duration = std::atof(argv[2]);
    std::vector<shoal::PlantState> base;
    for (double step : {0.02, 0.01, 0.005, 0.001}) {
      shoal::Scenario s = ref;
      s.vehicle.integrator_step_s = step;
      shoal::Swarm swarm(s, duration);
      swarm.Run(nullptr);
      if (base.empty()) {
        for (const auto& f : swarm.followers()) base.push_back(f->state());
      }
      double max_diff = 0.0;
      for (std::size_t i = 0; i < base.size(); ++i) {
        const auto& p = swarm.followers()[i]->state().eta;
        max_diff = std::max(max_diff, (p.head<3>() - base[i].eta.head<3>()).norm());
      }
      std::printf("step %.3f s: converged at %.2f s, max |p - p(20 ms)| at t = %.0f s: %.3e m\n",
                  step, swarm.metrics().convergence_time_s(), duration, max_diff);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  }
  return 0;
}

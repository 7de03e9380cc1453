#include "leader/leader_app.h"

#include <CLI/CLI.hpp>
#include <memory>

namespace shoal {

health_t LeaderApp::Health(Micros utime) const {
  health_t h = health_t();
  h.utime = utime;
  h.vehicle_id = 0;
  h.ticks = next_tick();
  return h;
}

int LeaderMain(int argc, char** argv) {
  CLI::App app{"Shoal leader process: publishes the scenario's leader path"};
  return ClockedNodeMain(
      &app, argc, argv, "shoal_leader", [](const Scenario&) { return true; },
      [](const NodeContext& c) {
        return std::make_unique<LeaderApp>(c.scenario, c.mode, c.t0_ns, c.duration_s, c.bus,
                                           c.rx_bus);
      });
}

}  // namespace shoal

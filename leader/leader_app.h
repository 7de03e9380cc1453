// The leader process (id 0): publishes the scenario's leader path, one state per tick. It
// receives nothing but (lockstep) the clock (runtime/clocked_node.h).
#pragma once

#include <cstdint>

#include "core/leader.h"
#include "runtime/clocked_node.h"

namespace shoal {

class LeaderApp : public ClockedNode {
 public:
  /// Buses as ClockedNode.
  LeaderApp(const Scenario& s, Mode mode, std::int64_t t0_ns, double duration_s, Bus* bus,
            Bus* rx_bus)
      : ClockedNode(s, 0, mode, t0_ns, duration_s, bus, rx_bus), leader_(s) {}

 private:
  const StateMsg& StepAt(Micros now) override { return leader_.Tick(now); }
  health_t Health(Micros utime) const override;

  Leader leader_;
};

/// The whole main() of shoal_leader: parse flags, load, run.
int LeaderMain(int argc, char** argv);

}  // namespace shoal

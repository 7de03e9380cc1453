// The core's view of a vehicle_state_t message (no LCM in core/).
#pragma once

#include <cstdint>

#include "core/types.h"

namespace shoal {

struct StateMsg {
  int vehicle_id = 0;
  std::int32_t seq = 0;
  Micros utime = 0;
  Vec5 eta = Vec5::Zero();
  Vec5 nu = Vec5::Zero();
  Vec5 eta_dot = Vec5::Zero();
  Vec5 accel_cmd = Vec5::Zero();
  Vec5 tau = Vec5::Zero();
  std::int32_t flags = 0;

  // Same values as vehicle_state_t::FLAG_*.
  static constexpr std::int32_t kFlagSaturated = 1;
  static constexpr std::int32_t kFlagStaleNeighbour = 2;
  static constexpr std::int32_t kFlagLeader = 4;
  static constexpr std::int32_t kFlagControllerReset = 8;  // a controller_reset window

  /// True if every numeric field is finite (NaN/Inf never reach the control law).
  bool AllFinite() const {
    return eta.allFinite() && nu.allFinite() && eta_dot.allFinite() && accel_cmd.allFinite() &&
           tau.allFinite();
  }
};

}  // namespace shoal

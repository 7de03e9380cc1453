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
    // x * 0 is +-0 for a finite x and NaN for +-Inf and NaN, and NaN survives every sum:
    // one comparison for the 25 numbers of every message a follower receives, where
    // Eigen's allFinite() tests each vector with a branch and costs twice the instructions.
    return ZeroIfFinite(eta) + ZeroIfFinite(nu) + ZeroIfFinite(eta_dot) +
               ZeroIfFinite(accel_cmd) + ZeroIfFinite(tau) ==
           0.0;
  }

 private:
  static double ZeroIfFinite(const Vec5& v) {
    return (v(0) * 0.0 + v(1) * 0.0) + (v(2) * 0.0 + v(3) * 0.0) + v(4) * 0.0;
  }
};

}  // namespace shoal

// The core's view of a vehicle_state_t message (no LCM in core/).
#pragma once

#include <cstdint>
#include <cstring>

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
  /// Always inlined: it runs for every delivery, and a link-time optimised build that
  /// sees it called from many files otherwise keeps one out-of-line copy (4 % of shoal sim).
  [[gnu::always_inline]] bool AllFinite() const {
    // x * 0 is +-0 for a finite x and NaN for +-Inf and NaN, and NaN survives every sum:
    // one comparison for the 25 numbers of every message a follower receives. Two numbers
    // per SSE2 operation, which every x86-64 has: where Eigen's allFinite() tests each
    // vector with a branch, this is a third of its instructions.
    const Pair z = {0.0, 0.0};
    const Pair pairs = ((Head(eta) * z + Head(nu) * z) + (Head(eta_dot) * z + Head(accel_cmd) * z)) +
                       ((Mid(eta) * z + Mid(nu) * z) + (Mid(eta_dot) * z + Mid(accel_cmd) * z)) +
                       (Head(tau) * z + Mid(tau) * z);
    const double lasts =
        (eta(4) * 0.0 + nu(4) * 0.0) + (eta_dot(4) * 0.0 + accel_cmd(4) * 0.0) + tau(4) * 0.0;
    return pairs[0] + pairs[1] + lasts == 0.0;
  }

 private:
  using Pair = double __attribute__((vector_size(16)));
  static Pair Head(const Vec5& v) { return Load(v.data()); }
  static Pair Mid(const Vec5& v) { return Load(v.data() + 2); }
  static Pair Load(const double* p) {
    Pair r;
    std::memcpy(&r, p, sizeof r);
    return r;
  }
};

}  // namespace shoal

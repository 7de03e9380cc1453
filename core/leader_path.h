// Paths of the leader (id 0): the paper's helix, a straight line, or waypoints.
#pragma once

#include "core/scenario.h"

namespace shoal {

/// Position, attitude and their rates of the leader at time t.
/// Attitude follows the path tangent: psi = atan2(y', x'), theta = atan2(-z', |(x', y')|).
struct LeaderSample {
  Vec5 eta = Vec5::Zero();
  Vec5 eta_dot = Vec5::Zero();
  Vec5 nu = Vec5::Zero();  // J(eta)^{-1} eta_dot
};

class LeaderPath {
 public:
  explicit LeaderPath(const LeaderConfig& c);
  /// What a caller needs of a sample.
  enum class Parts {
    kAll,
    /// What paper Example 2's uncertain factor reads: eta except theta, and eta_dot.
    /// theta (eta(3)) and nu are left zero, without their atan2 and J^{-1}.
    kFactor,
  };
  /// The sample at t_s.
  LeaderSample At(double t_s, Parts parts = Parts::kAll) const;

 private:
  // Position, velocity, acceleration of the path point (NED).
  void Point(double t, Vec3* p, Vec3* v, Vec3* a) const;

  LeaderConfig c_;
  std::vector<double> seg_start_s_;  // waypoints: time at which each segment starts
  double total_s_ = 0.0;
};

}  // namespace shoal

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
  /// The sample at t_s.
  LeaderSample At(double t_s) const;

  /// What paper Example 2's uncertain factor reads of the sample at t_s.
  struct FactorSample {
    Vec3 p = Vec3::Zero();  // eta(0..2)
    // sin eta(4): the horizontal velocity's ratio y' / |(x', y')|; at rest at the end of
    // waypoints, the last segment's; 0 moving straight up or down, or at rest otherwise.
    double sin_psi = 0.0;
    Vec5 eta_dot = Vec5::Zero();  // as At gives it
  };
  /// The factor's part of At(t_s): sin psi without atan2 and sin (equal to
  /// sin(At(t_s).eta(4)) within rounding), and no theta or J^{-1}.
  FactorSample FactorAt(double t_s) const;

 private:
  // Position, velocity, acceleration of the path point (NED).
  void Point(double t, Vec3* p, Vec3* v, Vec3* a) const;
  // The attitude's rates (theta_dot, psi_dot) of a path whose velocity is v, acceleration
  // a and horizontal speed h (h2 its square), h > 1e-9.
  static void Rates(const Vec3& v, const Vec3& a, double h2, double h, double* theta_dot,
                    double* psi_dot);

  LeaderConfig c_;
  std::vector<double> seg_start_s_;  // waypoints: time at which each segment starts
  double total_s_ = 0.0;
};

}  // namespace shoal

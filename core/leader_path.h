// Paths of the leader (id 0): the paper's helix, a straight line, or waypoints.
#pragma once

#include <limits>

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
  /// The paper's helix at a whole second t: the slower angle's cosine and sine, the
  /// velocity, its horizontal part h, and the attitude, found by libm. A sample of the helix
  /// is taken from the anchor of the second it falls in: the angle moved on by a short
  /// series (ShiftAngle) and the attitude by the arctangent's series of the turn since the
  /// anchor. A sample is thus a function of its time alone: a caller that keeps the anchor
  /// between calls gets the same bits as one that does not, and pays libm once a simulated
  /// second rather than a sincos a sample, and for At two atan2 more (a third of the
  /// leader's cost in shoal sim). Other paths ignore it.
  struct HelixAnchor {
    // NaN: none yet. Equal to no second, negative ones included.
    double t = std::numeric_limits<double>::quiet_NaN();
    double cb = 1.0, sb = 0.0;
    Vec3 v = Vec3::Zero();
    double h = 0.0, psi = 0.0, theta = 0.0;
  };

  explicit LeaderPath(const LeaderConfig& c);
  /// The sample at t_s. `anchor`: the caller's, kept between calls (may be null).
  LeaderSample At(double t_s, HelixAnchor* anchor = nullptr) const;

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
  FactorSample FactorAt(double t_s, HelixAnchor* anchor = nullptr) const;

 private:
  // Position, velocity, acceleration of the path point (NED); of the helix, from the
  // anchor of t's second (`anchor` kept by the caller, or null).
  void Point(double t, HelixAnchor* anchor, Vec3* p, Vec3* v, Vec3* a) const;
  const HelixAnchor& AnchorOf(double t, HelixAnchor* kept, HelixAnchor* local) const;
  // The attitude's rates (theta_dot, psi_dot) of a path whose velocity is v, acceleration
  // a and horizontal speed h (h2 its square), h > 1e-9.
  static void Rates(const Vec3& v, const Vec3& a, double h2, double h, double* theta_dot,
                    double* psi_dot);

  LeaderConfig c_;
  std::vector<double> seg_start_s_;  // waypoints: time at which each segment starts
  double total_s_ = 0.0;
};

}  // namespace shoal

#include "core/metrics.h"

#include <algorithm>

#include "core/control.h"

namespace shoal {

namespace {
// Squares of ErrorsOf's norms (Eigen's norm() is the square root of squaredNorm()).
FormationErrors SquaredErrorsOf(const StateMsg& f, const Vec3& offset, const StateMsg& l) {
  FormationErrors e;
  e.position_m = ((f.eta.head<3>() - offset) - l.eta.head<3>()).squaredNorm();
  e.velocity_mps = (f.eta_dot - l.eta_dot).squaredNorm();
  const Eigen::Vector2d d(WrapAngle(f.eta(3) - l.eta(3)), WrapAngle(f.eta(4) - l.eta(4)));
  e.attitude_rad = d.squaredNorm();
  return e;
}

// sqrt(sq) <= tol, without the square root unless sq is within rounding of tol^2.
bool RootAtMost(double sq, double tol) {
  const double t2 = tol * tol;
  if (tol > 0.0 && sq < t2 * (1.0 - 1e-12)) return true;
  if (tol > 0.0 && sq > t2 * (1.0 + 1e-12)) return false;
  return std::sqrt(sq) <= tol;
}
/// The larger of two squared errors, NaN once either is: a follower's NaN state is the
/// worst error there is, which std::max (keeping its first argument) would drop.
double WorseOf(double a, double b) { return a > b || a != a ? a : b; }

}  // namespace

FormationErrors ErrorsOf(const StateMsg& f, const Vec3& offset, const StateMsg& l) {
  FormationErrors e;
  e.position_m = ((f.eta.head<3>() - offset) - l.eta.head<3>()).norm();
  e.velocity_mps = (f.eta_dot - l.eta_dot).norm();
  const Vec5 d = EtaDiff(f.eta, l.eta);
  e.attitude_rad = d.tail<2>().norm();
  return e;
}

FormationMetrics::FormationMetrics(const std::vector<Vec3>& offsets, const MetricsConfig& tol)
    : offsets_(offsets), tol_(tol), final_sq_(offsets.size()), final_(offsets.size()) {}

void FormationMetrics::Add(const StateMsg& leader, const std::vector<const StateMsg*>& followers) {
  const double t = ToSeconds(leader.utime);
  bool violating = false;
  FormationErrors worst;
  for (std::size_t i = 0; i < followers.size(); ++i) {
    const FormationErrors e = SquaredErrorsOf(*followers[i], offsets_[i], leader);
    final_sq_[i] = e;
    worst.position_m = WorseOf(worst.position_m, e.position_m);
    worst.velocity_mps = WorseOf(worst.velocity_mps, e.velocity_mps);
    worst.attitude_rad = WorseOf(worst.attitude_rad, e.attitude_rad);
    if (!(RootAtMost(e.position_m, tol_.position_tol_m) &&
          RootAtMost(e.velocity_mps, tol_.velocity_tol_mps))) {
      violating = true;
    }
  }
  max_position_sq_ = WorseOf(max_position_sq_, worst.position_m);
  worst_sq_ = worst;
  if (violating) {
    pending_start_ = true;
  } else if (pending_start_) {
    conv_start_t_ = t;
    pending_start_ = false;
  }
  last_violating_ = violating;
  last_t_ = t;
  ++samples_;
}

double FormationMetrics::convergence_time_s() const {
  if (!converged()) return -1.0;
  return conv_start_t_;
}

}  // namespace shoal

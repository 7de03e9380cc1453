#include "core/metrics.h"

#include <algorithm>

#include "core/control.h"

namespace shoal {

FormationErrors ErrorsOf(const StateMsg& f, const Vec3& offset, const StateMsg& l) {
  FormationErrors e;
  e.position_m = ((f.eta.head<3>() - offset) - l.eta.head<3>()).norm();
  e.velocity_mps = (f.eta_dot - l.eta_dot).norm();
  const Vec5 d = EtaDiff(f.eta, l.eta);
  e.attitude_rad = d.tail<2>().norm();
  return e;
}

FormationMetrics::FormationMetrics(const std::vector<Vec3>& offsets, const MetricsConfig& tol)
    : offsets_(offsets), tol_(tol), final_(offsets.size()) {}

void FormationMetrics::Add(const StateMsg& leader, const std::vector<const StateMsg*>& followers) {
  const double t = ToSeconds(leader.utime);
  bool violating = false;
  FormationErrors worst;
  for (std::size_t i = 0; i < followers.size(); ++i) {
    const FormationErrors e = ErrorsOf(*followers[i], offsets_[i], leader);
    final_[i] = e;
    worst.position_m = std::max(worst.position_m, e.position_m);
    worst.velocity_mps = std::max(worst.velocity_mps, e.velocity_mps);
    worst.attitude_rad = std::max(worst.attitude_rad, e.attitude_rad);
    if (!(e.position_m <= tol_.position_tol_m && e.velocity_mps <= tol_.velocity_tol_mps)) {
      violating = true;
    }
  }
  max_position_ = std::max(max_position_, worst.position_m);
  final_worst_ = worst;
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

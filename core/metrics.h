// Formation metrics (definitions in docs/metrics.md), shared by shoal sim and the tools.
//   position error e_p,i = ||(p_i - d_i) - p_0||      (x, y, z only)
//   velocity error e_v,i = ||eta_dot_i - eta_dot_0||  (all five components)
//   attitude error e_a,i = ||wrap(theta_i - theta_0), wrap(psi_i - psi_0)||
//   converged at the earliest sample time after which every follower stays within
//   position_tol_m and velocity_tol_mps to the end of the run.
#pragma once

#include <cmath>
#include <vector>

#include "core/scenario.h"
#include "core/state_msg.h"

namespace shoal {

struct FormationErrors {
  double position_m = 0.0;
  double velocity_mps = 0.0;
  double attitude_rad = 0.0;
};

/// Errors of one follower state against the leader state at the same time.
FormationErrors ErrorsOf(const StateMsg& follower, const Vec3& offset, const StateMsg& leader);

class FormationMetrics {
 public:
  FormationMetrics(const std::vector<Vec3>& offsets, const MetricsConfig& tol);

  /// One sample: the leader's and every follower's state at one time (followers[i-1]).
  void Add(const StateMsg& leader, const std::vector<const StateMsg*>& followers);

  bool converged() const { return samples_ > 0 && !last_violating_; }
  /// Earliest time after which all followers stayed within tolerance; -1 if not converged.
  double convergence_time_s() const;
  /// Worst follower at the last sample.
  const FormationErrors& final_worst() const {
    final_worst_ = Root(worst_sq_);
    return final_worst_;
  }
  /// Per-follower errors at the last sample.
  const std::vector<FormationErrors>& final_errors() const {
    for (std::size_t i = 0; i < final_.size(); ++i) final_[i] = Root(final_sq_[i]);
    return final_;
  }
  /// Worst position error over the whole run and at the current sample.
  double max_position_error_m() const { return std::sqrt(max_position_sq_); }
  double current_worst_position_m() const { return std::sqrt(worst_sq_.position_m); }
  std::int64_t samples() const { return samples_; }
  double last_time_s() const { return last_t_; }

 private:
  std::vector<Vec3> offsets_;
  MetricsConfig tol_;
  std::int64_t samples_ = 0;
  bool last_violating_ = false;
  double last_t_ = 0.0;
  double conv_start_t_ = 0.0;  // time of the first sample after the last violation
  bool pending_start_ = true;
  // A sample keeps the squares of the errors (each a squared norm): the worst and the
  // largest are the square roots of the largest squares, to the bit (sqrt is correctly
  // rounded and monotonic), and the square roots are taken when asked for, not three per
  // follower and sample.
  static FormationErrors Root(const FormationErrors& sq) {
    return {std::sqrt(sq.position_m), std::sqrt(sq.velocity_mps), std::sqrt(sq.attitude_rad)};
  }
  std::vector<FormationErrors> final_sq_;
  FormationErrors worst_sq_;
  double max_position_sq_ = 0.0;
  mutable std::vector<FormationErrors> final_;
  mutable FormationErrors final_worst_;
};

}  // namespace shoal

// Time-domain simulation of the delayed linear closed loop of protocol (10) (double
// integrators, constant delay on own and neighbour states, no uncertain factor):
//   x''(t) = -H (k1 x(t - tau) + k2 x'(t - tau)),   x(t) = x0, x'(t) = v0 for t <= 0.
// The 5 coordinates of eta decouple ((H (x) I_5)), so one coordinate per follower is the
// whole story: x is n-dimensional. Used to check the exact delay margin independently.
#pragma once

#include <Eigen/Dense>
#include <vector>

namespace shoal {

struct DelayedLinearTrace {
  std::vector<double> t_s;         ///< sample times
  std::vector<double> error_norm;  ///< ||[x; x']|| at each sample (the error vector e)
  bool finite = true;              ///< false: the state overflowed (stopped early)
};

/// Fixed-step RK4 with a history buffer. The step is tau / N (N = ceil(tau / max_step_s),
/// at least 1 when tau > 0), so the delayed state at full steps is a stored grid value;
/// at half steps it is the cubic Hermite interpolant of the two neighbouring grid values
/// and their derivatives (fourth order, like RK4). tau = 0 integrates the undelayed loop
/// with step max_step_s. Samples every `sample_s` (rounded to whole steps).
DelayedLinearTrace SimulateDelayedConsensus(const Eigen::MatrixXd& H, double k1, double k2,
                                            double tau_s, const Eigen::VectorXd& x0,
                                            const Eigen::VectorXd& v0, double horizon_s,
                                            double max_step_s = 1e-3, double sample_s = 0.1);

}  // namespace shoal

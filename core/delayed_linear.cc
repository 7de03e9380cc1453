#include "core/delayed_linear.h"

#include <algorithm>
#include <cmath>

namespace shoal {

DelayedLinearTrace SimulateDelayedConsensus(const Eigen::MatrixXd& H, double k1, double k2,
                                            double tau_s, const Eigen::VectorXd& x0,
                                            const Eigen::VectorXd& v0, double horizon_s,
                                            double max_step_s, double sample_s) {
  const Eigen::Index n = H.rows();
  const Eigen::Index m = 2 * n;
  const bool delayed = tau_s > 0.0;
  const long N = delayed ? std::max(1L, static_cast<long>(std::ceil(tau_s / max_step_s))) : 0;
  const double dt = delayed ? tau_s / static_cast<double>(N) : max_step_s;
  const long steps = static_cast<long>(std::ceil(horizon_s / dt));
  const long sample_every = std::max(1L, static_cast<long>(std::lround(sample_s / dt)));

  // e' = f(e, e_delayed) = [v; -H (k1 x_d + k2 v_d)].
  auto f = [&](const Eigen::VectorXd& y, const Eigen::VectorXd& yd) {
    Eigen::VectorXd out(m);
    out.head(n) = y.tail(n);
    out.tail(n) = -H * (k1 * yd.head(n) + k2 * yd.tail(n));
    return out;
  };

  Eigen::VectorXd y(m);
  y << x0, v0;
  // History ring of grid values y_k and derivatives y'_k for k in [current - N, current];
  // before t = 0 the state is the constant initial function (derivative 0).
  const long ring = N + 1;
  std::vector<Eigen::VectorXd> hy(ring, y), hd(ring, Eigen::VectorXd::Zero(m));
  auto slot = [&](long k) { return static_cast<std::size_t>(((k % ring) + ring) % ring); };

  DelayedLinearTrace trace;
  trace.t_s.push_back(0.0);
  trace.error_norm.push_back(y.norm());
  for (long k = 0; k < steps; ++k) {
    Eigen::VectorXd s1, s2, s3, s4;
    if (delayed) {
      const std::size_t a = slot(k - N), b = slot(k - N + 1);
      // Stage 1 uses y_{k-N}; it also defines the derivative stored at grid k.
      s1 = f(y, hy[a]);
      hd[slot(k)] = s1;
      hy[slot(k)] = y;
      // Delayed state half-way between grid k-N and k-N+1 (cubic Hermite), and at k-N+1.
      // With N = 1, k-N+1 = k: its value and derivative were just stored.
      // The initial function is constant, so on the grid interval ending at t = 0 the
      // derivative at its right end is 0 (the solution's derivative jumps at t = 0; using
      // the right-hand value there would cost two orders of accuracy).
      const Eigen::VectorXd zero = Eigen::VectorXd::Zero(m);
      const Eigen::VectorXd& db = (k - N + 1 == 0) ? zero : hd[b];
      const Eigen::VectorXd mid = 0.5 * (hy[a] + hy[b]) + (dt / 8.0) * (hd[a] - db);
      const Eigen::VectorXd end = hy[b];
      s2 = f(y + 0.5 * dt * s1, mid);
      s3 = f(y + 0.5 * dt * s2, mid);
      s4 = f(y + dt * s3, end);
    } else {
      s1 = f(y, y);
      const Eigen::VectorXd y2 = y + 0.5 * dt * s1;
      s2 = f(y2, y2);
      const Eigen::VectorXd y3 = y + 0.5 * dt * s2;
      s3 = f(y3, y3);
      const Eigen::VectorXd y4 = y + dt * s3;
      s4 = f(y4, y4);
    }
    y += (dt / 6.0) * (s1 + 2.0 * s2 + 2.0 * s3 + s4);
    if ((k + 1) % sample_every == 0 || k + 1 == steps) {
      const double norm = y.norm();
      trace.t_s.push_back(static_cast<double>(k + 1) * dt);
      trace.error_norm.push_back(norm);
      if (!std::isfinite(norm) || norm > 1e150) {
        trace.finite = false;
        break;
      }
    }
  }
  return trace;
}

}  // namespace shoal

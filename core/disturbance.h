// Uncertain factors acting on a follower.
#pragma once

#include <algorithm>
#include <cmath>

#include "core/leader_path.h"
#include "core/rng.h"
#include "core/scenario.h"

namespace shoal {

/// Paper Example 2's uncertain factor F~(x, v) (an acceleration in eta''), evaluated by the
/// caller at the delayed arguments x = eta(t - tau(t)), v = eta_dot(t - tau(t)).
inline Vec5 PaperExample2F(const Vec5& x, const Vec5& v) {
  Vec5 f;
  f(0) = 0.4 * std::tanh(v(0));
  f(1) = 0.01 * std::sin(x(1)) - 0.45 * std::tanh(v(1));
  f(2) = -0.01 * std::cos(x(2));
  f(3) = 0.48 * std::tanh(v(3));
  f(4) = 0.02 * std::sin(x(4)) - 0.5 * std::tanh(v(4));
  return f;
}

/// What the simulated world knows besides each vehicle's own state: the leader's path,
/// for the paper's uncertain factor relative to the leader. One instance may be shared by
/// the followers of a process; it caches its last answer (followers ask for the same time).
class Environment {
 public:
  explicit Environment(const LeaderConfig& c) : path_(c) {}
  const LeaderPath& leader_path() const { return path_; }

  /// f(x_0(t), v_0(t)) of paper Example 2 on the leader's path at time t.
  const Vec5& LeaderPaperF(double t_s) const {
    if (!valid_ || t_s != t_) {
      const LeaderSample l = path_.At(t_s);
      f0_ = PaperExample2F(l.eta, l.eta_dot);
      t_ = t_s;
      valid_ = true;
    }
    return f0_;
  }

 private:
  LeaderPath path_;
  mutable bool valid_ = false;
  mutable double t_ = 0.0;
  mutable Vec5 f0_ = Vec5::Zero();
};

/// First-order Gauss-Markov current speed (Fossen 2011, sec. 8.3):
/// V_dot + mu V = w, w white with standard deviation noise_mps, V clamped to [min, max];
/// direction fixed. Euler-Maruyama per control period.
class OceanCurrent {
 public:
  OceanCurrent(const OceanCurrentConfig& c, Rng rng) : c_(c), rng_(rng), speed_(c.speed_mps) {}

  /// Current velocity (NED) now; then advances the speed by dt.
  Vec3 Step(double dt) {
    const Vec3 v(speed_ * std::cos(c_.direction_rad), speed_ * std::sin(c_.direction_rad), 0.0);
    // The process relaxes towards the configured speed (mean), not towards zero.
    speed_ += -c_.mu_per_s * (speed_ - c_.speed_mps) * dt + c_.noise_mps * std::sqrt(dt) * rng_.Normal();
    speed_ = std::clamp(speed_, c_.min_speed_mps, c_.max_speed_mps);
    return v;
  }

 private:
  OceanCurrentConfig c_;
  Rng rng_;
  double speed_;
};

}  // namespace shoal

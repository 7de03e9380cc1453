// Uncertain factors acting on a follower.
#pragma once

#include <algorithm>
#include <cmath>

#include "core/channel_model.h"
#include "core/fossen.h"
#include "core/leader_path.h"
#include "core/rng.h"
#include "core/scenario.h"

namespace shoal {

/// tanh to within 4e-15 relative (tests/unit: against std::tanh), about twice as fast as
/// glibc's (which goes through expm1): odd Taylor series to x^11 below 1/16, where
/// 1 - 2/(e^{2|x|} + 1) would cancel, the exp form above, +-1 beyond 19.
inline double FastTanh(double x) {
  const double ax = std::fabs(x);
  if (ax < 0.0625) {
    const double x2 = x * x;
    return x * (1.0 + x2 * (-1.0 / 3.0 + x2 * (2.0 / 15.0 + x2 * (-17.0 / 315.0 +
                x2 * (62.0 / 2835.0 + x2 * (-1382.0 / 155925.0))))));
  }
  if (!(ax <= 19.0)) return std::isnan(x) ? x : std::copysign(1.0, x);
  return std::copysign(1.0 - 2.0 / (std::exp(2.0 * ax) + 1.0), x);
}

/// Paper Example 2's uncertain factor F~(x, v) (an acceleration in eta'') given
/// sin x(1), cos x(2) and sin x(4).
inline Vec5 PaperExample2F(double sin_x1, double cos_x2, double sin_x4, const Vec5& v) {
  return Vec5Of(0.4 * FastTanh(v(0)), 0.01 * sin_x1 - 0.45 * FastTanh(v(1)), -0.01 * cos_x2,
                0.48 * FastTanh(v(3)), 0.02 * sin_x4 - 0.5 * FastTanh(v(4)));
}

/// Paper Example 2's uncertain factor F~(x, v), evaluated by the caller at the delayed
/// arguments x = eta(t - tau(t)), v = eta_dot(t - tau(t)).
inline Vec5 PaperExample2F(const Vec5& x, const Vec5& v) {
  return PaperExample2F(std::sin(x(1)), std::cos(x(2)), std::sin(x(4)), v);
}

/// sin and cos of an argument that moves little from one call to the next (a vehicle's
/// delayed state, tick after tick): carried by ShiftAngle (core/fossen.h) from the last
/// argument, computed afresh at the first call, every kRefresh calls (so that rounding
/// cannot accumulate) and after a step beyond ShiftAngle's series.
class CarriedSinCos {
 public:
  static constexpr int kRefresh = 50;
  void Set(double x) {
    const double d = x - x_;
    if (age_ == 0 || std::abs(d) > 0.05) {
      sin_ = std::sin(x);
      cos_ = std::cos(x);
    } else {
      ShiftAngle(x_, sin_, cos_, d, &sin_, &cos_);
    }
    x_ = x;
    age_ = (age_ + 1) % kRefresh;
  }
  double sin() const { return sin_; }
  double cos() const { return cos_; }
  /// The next Set computes afresh.
  void Reset() { age_ = 0; }
  /// What is carried from one Set to the next: a follower's checkpoint holds it, so that a
  /// resumed follower goes on to the bit as the uninterrupted one does.
  struct Carried {
    double x = 0.0, sin = 0.0, cos = 1.0;
    int age = 0;
  };
  Carried carried() const { return {x_, sin_, cos_, age_}; }
  /// Goes on from `c`; one that is not finite or out of range computes afresh instead.
  void Restore(const Carried& c) {
    const bool ok = std::isfinite(c.x) && std::isfinite(c.sin) && std::isfinite(c.cos) &&
                    c.age >= 0 && c.age < kRefresh;
    x_ = ok ? c.x : 0.0;
    sin_ = ok ? c.sin : 0.0;
    cos_ = ok ? c.cos : 1.0;
    age_ = ok ? c.age : 0;
  }

 private:
  double x_ = 0.0, sin_ = 0.0, cos_ = 1.0;
  int age_ = 0;
};

/// What the simulated world knows besides each vehicle's own state: the leader's path,
/// for the paper's uncertain factor relative to the leader. One instance may be shared by
/// the followers of a process, also across threads: reads never write it (At writes only
/// the anchor its caller passes). The owner may
/// Warm() it with the time every follower is about to ask for (all followers ask for the
/// same time in a tick), before the followers step.
class Environment {
 public:
  /// `disturbance_delay`: the delay model at whose tau(t) the uncertain factor's
  /// arguments are taken (the scenario's default link delay).
  /// `leader_factor` false: f0 is not needed (the factor is absolute, not relative to the
  /// leader) and stays zero, so that the leader's path is not evaluated for nothing.
  Environment(const LeaderConfig& c, const DelayConfig& disturbance_delay,
              bool leader_factor = true)
      : path_(c), delay_(disturbance_delay), leader_factor_(leader_factor) {}
  const LeaderPath& leader_path() const { return path_; }

  /// The uncertain factor's delay at tick time `now`, in whole microseconds (its
  /// deterministic part: NominalDelaySeconds), and f(x_0, v_0) of paper Example 2 on the
  /// leader's path at max(0, now - delay).
  struct DelayedLeader {
    Micros delay_us = 0;
    Vec5 f0 = Vec5::Zero();
  };
  /// `anchor`: the caller's own, kept between calls (LeaderPath::HelixAnchor; may be
  /// null): the answer is the same with or without it.
  DelayedLeader At(Micros now, LeaderPath::HelixAnchor* anchor = nullptr) const {
    if (valid_ && now == now_) return cached_;
    return Compute(now, anchor);
  }

  /// Caches At(now). Not to be called while followers step.
  void Warm(Micros now) {
    if (valid_ && now == now_) return;
    cached_ = Compute(now, &anchor_);
    now_ = now;
    valid_ = true;
  }

 private:
  DelayedLeader Compute(Micros now, LeaderPath::HelixAnchor* anchor) const {
    DelayedLeader d;
    d.delay_us = static_cast<Micros>(
        std::llround(std::min(NominalDelaySeconds(delay_, ToSeconds(now)) * 1e6, 1e18)));
    if (!leader_factor_) return d;
    const LeaderPath::FactorSample l =
        path_.FactorAt(std::max(0.0, ToSeconds(now - d.delay_us)), anchor);
    d.f0 = PaperExample2F(std::sin(l.p(1)), std::cos(l.p(2)), l.sin_psi, l.eta_dot);
    return d;
  }

  LeaderPath path_;
  DelayConfig delay_;
  bool leader_factor_ = true;
  bool valid_ = false;
  Micros now_ = 0;
  DelayedLeader cached_;
  LeaderPath::HelixAnchor anchor_;  // Warm's
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

// Uncertain factors: the fast tanh of paper Example 2's F against the C library, the
// environment's per-tick cache against direct evaluation, and the leader's path against
// its defining formulas.
#include "core/disturbance.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>
#include <vector>

#include "core/control.h"
#include "core/rng.h"

namespace shoal {
namespace {

TEST(FastTanhTest, MatchesStdTanhToFewUlpsEverywhere) {
  Rng rng(3, 4, 5);
  double worst = 0.0;
  for (int k = 0; k < 200000; ++k) {
    // Log-uniform magnitudes from 1e-12 to 40, both signs, plus the branch edges.
    double x = std::pow(10.0, -12.0 + 13.6 * rng.Uniform());
    if (rng.Uniform() < 0.5) x = -x;
    if (k < 6) x = std::array<double, 6>{0.0625, -0.0625, 0.06249999999, 19.0, 19.0000001, 1e-300}[k];
    const double ref = std::tanh(x);
    const double rel = ref == 0.0 ? std::fabs(FastTanh(x)) : std::fabs(FastTanh(x) - ref) / std::fabs(ref);
    worst = std::max(worst, rel);
  }
  EXPECT_LT(worst, 4e-15);
  EXPECT_EQ(FastTanh(0.0), 0.0);
  EXPECT_EQ(FastTanh(1e3), 1.0);
  EXPECT_EQ(FastTanh(-1e3), -1.0);
  EXPECT_EQ(FastTanh(std::numeric_limits<double>::infinity()), 1.0);
  EXPECT_TRUE(std::isnan(FastTanh(std::numeric_limits<double>::quiet_NaN())));
  // Odd, and continuous across the branch switch (the two forms agree to a few ulps there).
  EXPECT_EQ(FastTanh(-0.3), -FastTanh(0.3));
  EXPECT_NEAR(FastTanh(std::nextafter(0.0625, 0.0)), FastTanh(0.0625), 4e-16);
}

// The follower carries sin and cos of its delayed state from tick to tick: along random
// walks of tick-sized steps (millimetres to centimetres, at arguments of up to a few
// hundred), with now and then a jump beyond the series, they stay within a few ulps of
// std::sin and std::cos of the argument itself, and a jump or a refresh gives them exactly.
TEST(CarriedSinCosTest, StaysWithinFewUlpsOfStdAlongSmallSteps) {
  Rng rng(8, 9, 10);
  double worst = 0.0;
  int exact_after_jump = 0;
  for (int walk = 0; walk < 40; ++walk) {
    CarriedSinCos c;
    double x = (rng.Uniform() - 0.5) * 600.0;
    for (int k = 0; k < 5000; ++k) {
      const bool jump = rng.Uniform() < 0.002;
      x += jump ? 0.5 + rng.Uniform() : (rng.Uniform() - 0.5) * 0.06;
      c.Set(x);
      if (jump) {
        exact_after_jump += c.sin() == std::sin(x) && c.cos() == std::cos(x);
        continue;
      }
      worst = std::max({worst, std::fabs(c.sin() - std::sin(x)), std::fabs(c.cos() - std::cos(x))});
    }
  }
  EXPECT_LT(worst, 2e-15);
  EXPECT_GT(worst, 0.0);  // the series was used (else this tests std::sin against itself)
  EXPECT_GT(exact_after_jump, 100);
  // The first Set and one after Reset compute afresh.
  CarriedSinCos c;
  c.Set(3.0);
  EXPECT_EQ(c.sin(), std::sin(3.0));
  c.Set(3.01);
  c.Reset();
  c.Set(3.02);
  EXPECT_EQ(c.sin(), std::sin(3.02));
  EXPECT_EQ(c.cos(), std::cos(3.02));
}

TEST(EnvironmentTest, WarmedAnswerEqualsDirectEvaluation) {
  LeaderConfig leader;  // the paper's helix
  const DelayConfig delay{DelayKind::kSinusoid, 0.1, 0.05, 1.0};
  Environment cold(leader, delay), warm(leader, delay);
  for (Micros now : {Micros{0}, Micros{20000}, Micros{60000}, Micros{123440000}}) {
    warm.Warm(now);
    const auto a = cold.At(now), b = warm.At(now);
    EXPECT_EQ(a.delay_us, b.delay_us);
    EXPECT_EQ(a.f0, b.f0);
    const Micros expect_delay = std::llround((0.1 + 0.05 * std::cos(ToSeconds(now))) * 1e6);
    EXPECT_EQ(a.delay_us, expect_delay);
    const double t = std::max(0.0, ToSeconds(now - expect_delay));
    const LeaderPath::FactorSample f = LeaderPath(leader).FactorAt(t);
    EXPECT_EQ(a.f0, PaperExample2F(std::sin(f.p(1)), std::cos(f.p(2)), f.sin_psi, f.eta_dot));
    // Within rounding of the factor of the whole sample, whose heading's sine goes through
    // atan2 and sin (0.02 sin psi: a few 1e-18).
    const LeaderSample l = LeaderPath(leader).At(t);
    EXPECT_LT((a.f0 - PaperExample2F(l.eta, l.eta_dot)).cwiseAbs().maxCoeff(), 1e-17);
  }
  // A warmed environment asked about another time computes that time, not the cached one.
  warm.Warm(20000);
  EXPECT_EQ(warm.At(40000).f0, cold.At(40000).f0);
}

// The paths a leader may follow, each at times that cover its cases.
std::vector<std::pair<LeaderConfig, std::vector<double>>> LeaderCases() {
  std::vector<std::pair<LeaderConfig, std::vector<double>>> cases;
  std::vector<double> times;
  for (int k = 0; k <= 400; ++k) times.push_back(k * 7.31);
  cases.push_back({LeaderConfig{}, times});  // the paper's helix
  LeaderConfig line;
  line.path = PathKind::kLine;
  line.velocity_mps = Vec3(0.6, -1.1, 0.2);
  cases.push_back({line, {0.0, 1.0, 100.0}});
  line.velocity_mps = Vec3(0.0, 0.0, 0.5);  // straight down: no heading from the velocity
  cases.push_back({line, {0.0, 3.0}});
  LeaderConfig wp;
  wp.path = PathKind::kWaypoints;
  wp.waypoints_m = {Vec3(0, 0, 0), Vec3(10, 5, 2), Vec3(10, 20, 0)};
  cases.push_back({wp, {0.0, 3.0, 12.0, 25.0, 1000.0}});  // the last: at rest at the end
  return cases;
}

TEST(LeaderPathTest, HelixIsThePapersFormulas) {
  const LeaderPath path{LeaderConfig{}};
  const double wa = 0.0022 * kPi, wb = 0.0011 * kPi;
  for (int k = -60; k <= 20000; ++k) {  // negative times too: before the run, as the paper's
    const double t = k * 0.0513;        // formulas give them
    const LeaderSample s = path.At(t);
    EXPECT_NEAR(s.eta(0), 60 * std::cos(wa * t) + 25 * std::sin(wb * t), 1e-12) << t;
    EXPECT_NEAR(s.eta(1), 60 * std::sin(wa * t) + 25 * std::cos(wb * t), 1e-12) << t;
    EXPECT_EQ(s.eta(2), -0.12 * t);
    EXPECT_NEAR(s.eta_dot(0), -60 * wa * std::sin(wa * t) + 25 * wb * std::cos(wb * t), 1e-14)
        << t;
    EXPECT_NEAR(s.eta_dot(1), 60 * wa * std::cos(wa * t) - 25 * wb * std::sin(wb * t), 1e-14)
        << t;
  }
}

// Every double of two samples, bit for bit.
bool SameSample(const LeaderSample& a, const LeaderSample& b) {
  return std::memcmp(a.eta.data(), b.eta.data(), sizeof(double) * 5) == 0 &&
         std::memcmp(a.eta_dot.data(), b.eta_dot.data(), sizeof(double) * 5) == 0 &&
         std::memcmp(a.nu.data(), b.nu.data(), sizeof(double) * 5) == 0;
}

bool SameFactor(const LeaderPath::FactorSample& a, const LeaderPath::FactorSample& b) {
  return std::memcmp(a.p.data(), b.p.data(), sizeof(double) * 3) == 0 &&
         std::memcmp(&a.sin_psi, &b.sin_psi, sizeof(double)) == 0 &&
         std::memcmp(a.eta_dot.data(), b.eta_dot.data(), sizeof(double) * 5) == 0;
}

// A kept anchor only saves work: the leader process, a vehicle process and shoal sim ask
// for the helix in different orders and must get the same bits (lockstep equals shoal sim).
TEST(LeaderPathTest, HelixSampleIsAFunctionOfTimeAlone) {
  const LeaderPath path{LeaderConfig{}};
  std::vector<double> times;
  for (int k = 0; k <= 3000; ++k) times.push_back(k * 0.02);            // ticks, in order
  for (int k = 0; k <= 300; ++k) times.push_back(59.9 - k * 0.0137);    // backwards
  Rng rng(7, 8, 9);
  for (int k = 0; k < 3000; ++k) times.push_back(1200.0 * rng.Uniform());  // anywhere
  for (double t : {0.0, 1.0, 0.9999999999999999, 1.0000000000000002, 999.0, 2999.98, -0.3,
                   -1.0, -1.7, -2.0}) {
    times.push_back(t);
  }
  LeaderPath::HelixAnchor kept, kept_factor;
  for (double t : times) {
    ASSERT_TRUE(SameSample(path.At(t, &kept), path.At(t))) << t;
    ASSERT_TRUE(SameFactor(path.FactorAt(t, &kept_factor), path.FactorAt(t))) << t;
    // One anchor shared by both kinds of sample, too.
    LeaderPath::HelixAnchor shared;
    path.FactorAt(std::floor(t) + 0.5, &shared);
    ASSERT_TRUE(SameSample(path.At(t, &shared), path.At(t))) << t;
  }
}

// The helix's attitude from its anchor, against atan2 of the sample's own velocity.
TEST(LeaderPathTest, HelixAttitudeIsTheVelocitysDirectionWithinRounding) {
  const LeaderPath path{LeaderConfig{}};
  LeaderPath::HelixAnchor kept;
  double worst = 0.0;
  for (int k = 0; k <= 150000; ++k) {
    const double t = k * 0.02;
    const LeaderSample s = path.At(t, &kept);
    const Vec3 v = s.eta_dot.head<3>();
    const double h = std::hypot(v.x(), v.y());
    worst = std::max(worst, std::abs(WrapAngle(s.eta(4) - std::atan2(v.y(), v.x()))));
    worst = std::max(worst, std::abs(s.eta(3) - std::atan2(-v.z(), h)));
  }
  EXPECT_LT(worst, 1e-15) << worst;
}

TEST(LeaderPathTest, NuIsJInverseOfEtaDot) {
  for (const auto& [config, times] : LeaderCases()) {
    const LeaderPath path(config);
    for (double t : times) {
      const LeaderSample s = path.At(t);
      const Vec5 expect = FossenModel::JInv(s.eta) * s.eta_dot;
      for (int i = 0; i < 5; ++i) {
        EXPECT_NEAR(s.nu(i), expect(i), 1e-14 * (1.0 + std::abs(expect(i))))
            << "path " << static_cast<int>(config.path) << " t " << t << " i " << i;
      }
    }
  }
}

TEST(LeaderPathTest, FactorSampleIsTheSamplesPositionRatesAndHeadingsSine) {
  for (const auto& [config, times] : LeaderCases()) {
    const LeaderPath path(config);
    for (double t : times) {
      const LeaderSample all = path.At(t);
      const LeaderPath::FactorSample f = path.FactorAt(t);
      EXPECT_EQ(f.p, all.eta.head<3>()) << t;
      EXPECT_EQ(f.eta_dot, all.eta_dot) << t;
      // The velocity's ratio against the sine of the heading: rounding apart (the
      // helix's heading, from its anchor, within a few units in the last place of atan2's).
      EXPECT_NEAR(f.sin_psi, std::sin(all.eta(4)), 1e-15) << "path "
          << static_cast<int>(config.path) << " t " << t;
    }
  }
}

}  // namespace
}  // namespace shoal

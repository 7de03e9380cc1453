// Formation metrics on synthetic states with known answers (definitions: docs/sim.md).
#include "core/metrics.h"

#include <gtest/gtest.h>

#include <cmath>

namespace shoal {
namespace {

StateMsg At(double t, const Vec5& eta, const Vec5& eta_dot) {
  StateMsg m;
  m.utime = static_cast<Micros>(t * 1e6);
  m.eta = eta;
  m.eta_dot = eta_dot;
  return m;
}

TEST(Metrics, ErrorsUseOffsetsOnlyForPositionAndWrapAngles) {
  const StateMsg leader = At(0, (Vec5() << 10, 20, 5, 0.1, 3.1).finished(),
                             (Vec5() << 1, 0, 0, 0, 0.01).finished());
  // At its slot (leader + offset) but for 3-4-0 m, heading across +-pi, velocity off.
  const StateMsg f = At(0, (Vec5() << 10 + 2 + 3, 20 - 1 + 4, 5, 0.1, -3.1).finished(),
                        (Vec5() << 1, 0.3, 0, 0, 0.01).finished());
  const FormationErrors e = ErrorsOf(f, Vec3(2, -1, 0), leader);
  EXPECT_NEAR(e.position_m, 5.0, 1e-12);
  EXPECT_NEAR(e.velocity_mps, 0.3, 1e-12);
  EXPECT_NEAR(e.attitude_rad, 2 * M_PI - 6.2, 1e-12);  // wrapped, not 6.2
}

// One follower whose position error is given per sample; velocity always within tol.
FormationMetrics RunPositionErrors(const std::vector<double>& pos_err, MetricsConfig tol = {}) {
  FormationMetrics m({Vec3::Zero()}, tol);
  for (std::size_t k = 0; k < pos_err.size(); ++k) {
    const StateMsg l = At(static_cast<double>(k), Vec5::Zero(), Vec5::Zero());
    const StateMsg f = At(static_cast<double>(k), (Vec5() << pos_err[k], 0, 0, 0, 0).finished(),
                          Vec5::Zero());
    m.Add(l, {&f});
  }
  return m;
}

TEST(Metrics, ConvergedAtTheFirstSampleAfterTheLastViolation) {
  const auto m = RunPositionErrors({9, 3, 0.4, 0.3, 0.7, 0.2, 0.1, 0.1});  // tol 0.5: last violation at t=4
  EXPECT_TRUE(m.converged());
  EXPECT_DOUBLE_EQ(m.convergence_time_s(), 5.0);
  EXPECT_DOUBLE_EQ(m.final_worst().position_m, 0.1);
  EXPECT_DOUBLE_EQ(m.max_position_error_m(), 9.0);
}

// The metrics keep squared errors and take square roots only when asked: every reported
// error must still be ErrorsOf's to the bit, and a follower exactly at, a hair below and a
// hair above the tolerance must be judged as sqrt(error^2) <= tol judges it.
TEST(Metrics, SquaredErrorsGiveErrorsOfsNumbersAndItsJudgementAtTheTolerance) {
  const double tol = 0.5;
  int judged_in = 0, judged_out = 0;
  for (int k = -40; k <= 40; ++k) {
    // A position error (0.3, 0.4 + k 1e-17, 0): its norm is tol give or take a few ulps
    // (the leader at the origin keeps the error's ulps).
    const double x = 0.3, y = 0.4 + k * 1e-17;
    FormationMetrics m({Vec3::Zero()}, MetricsConfig{tol, 1.0});
    const StateMsg l = At(0, (Vec5() << 0, 0, 0, 0.3, 3.0).finished(),
                          (Vec5() << 1, 0, 0, 0, 0).finished());
    const StateMsg f = At(0, (Vec5() << x, y, 0, -0.2, -3.0).finished(),
                          (Vec5() << 1.2, 0.1, 0, 0.01, 0).finished());
    m.Add(l, {&f});
    const FormationErrors e = ErrorsOf(f, Vec3::Zero(), l);
    EXPECT_EQ(m.final_errors()[0].position_m, e.position_m) << k;
    EXPECT_EQ(m.final_errors()[0].velocity_mps, e.velocity_mps) << k;
    EXPECT_EQ(m.final_errors()[0].attitude_rad, e.attitude_rad) << k;
    EXPECT_EQ(m.final_worst().position_m, e.position_m) << k;
    EXPECT_EQ(m.max_position_error_m(), e.position_m) << k;
    EXPECT_EQ(m.converged(), e.position_m <= tol) << k;
    (e.position_m <= tol ? judged_in : judged_out) += 1;
  }
  // Both sides of the tolerance were reached.
  EXPECT_GT(judged_in, 0);
  EXPECT_GT(judged_out, 0);
}

TEST(Metrics, NeverViolatingConvergesAtTheFirstSample) {
  const auto m = RunPositionErrors({0.1, 0.2, 0.1});
  EXPECT_TRUE(m.converged());
  EXPECT_DOUBLE_EQ(m.convergence_time_s(), 0.0);
}

TEST(Metrics, ViolatingAtTheEndIsNotConverged) {
  const auto m = RunPositionErrors({0.1, 0.2, 0.6});
  EXPECT_FALSE(m.converged());
  EXPECT_LT(m.convergence_time_s(), 0.0);
}

TEST(Metrics, VelocityToleranceCountsToo) {
  FormationMetrics m({Vec3::Zero()}, MetricsConfig{0.5, 0.05});
  for (int k = 0; k < 4; ++k) {
    const StateMsg l = At(k, Vec5::Zero(), Vec5::Zero());
    const double v = k < 2 ? 0.2 : 0.01;  // position fine all along, velocity late
    const StateMsg f = At(k, Vec5::Zero(), (Vec5() << v, 0, 0, 0, 0).finished());
    m.Add(l, {&f});
  }
  EXPECT_TRUE(m.converged());
  EXPECT_DOUBLE_EQ(m.convergence_time_s(), 2.0);
}

}  // namespace
}  // namespace shoal

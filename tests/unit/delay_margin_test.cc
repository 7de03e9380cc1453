// The exact delay margin against an independent check: time-domain simulation of the
// delayed closed loop x'' = -H (k1 x(t - tau) + k2 x'(t - tau)) just below and just above
// the margin, on topologies with real, complex and defective H.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include "core/delayed_linear.h"
#include "core/theory.h"
#include "core/topology.h"

namespace shoal {
namespace {

struct Case {
  std::string name;
  Eigen::MatrixXd H;
  double k1, k2;
};

Eigen::MatrixXd PaperH() {
  return Topology::Build(5, {{1, 3}, {2, 1}, {2, 5}, {3, 1}, {4, 5}, {5, 2}, {5, 4}}, {1, 3, 5})
      .H();
}

std::vector<Case> Cases() {
  return {
      // Paper Fig. 1: distinct real eigenvalues; the scenario's gains.
      {"paper", PaperH(), 0.18, 1.152},
      // Directed ring 1 -> 2 -> 3 -> 1, leader -> 1: a complex pair sets the margin.
      {"ring3", Topology::Build(3, {{1, 3}, {2, 1}, {3, 2}}, {1}).H(), 0.18, 1.152},
      // Ring of 4: a real eigenvalue and a complex pair; the pair is critical.
      {"ring4", Topology::Build(4, {{1, 4}, {2, 1}, {3, 2}, {4, 3}}, {1}).H(), 0.5, 1.0},
      // Chain leader -> 1 -> 2 -> 3: H = I - N, one 3x3 Jordan block (defective).
      {"chain3", Topology::Build(3, {{2, 1}, {3, 2}}, {1}).H(), 0.18, 1.152},
  };
}

/// max of the error norm over samples with t in [from, to].
double MaxOver(const DelayedLinearTrace& tr, double from, double to) {
  double m = 0.0;
  for (std::size_t i = 0; i < tr.t_s.size(); ++i) {
    if (tr.t_s[i] >= from && tr.t_s[i] <= to) m = std::max(m, tr.error_norm[i]);
  }
  return m;
}

/// Growth of the error norm between two late windows of a long run: < 1 decays, > 1 grows.
/// Late windows so that transients (a defective H's t^k e^{st} terms) have played out.
double LateGrowth(const Case& c, double tau) {
  const int n = static_cast<int>(c.H.rows());
  Eigen::VectorXd x0(n), v0(n);
  for (int i = 0; i < n; ++i) {
    x0(i) = 1.0 + 0.3 * i;
    v0(i) = -0.5 + 0.2 * i;
  }
  const double T = 400.0;
  const DelayedLinearTrace tr = SimulateDelayedConsensus(c.H, c.k1, c.k2, tau, x0, v0, T);
  if (!tr.finite) return 1e300;  // overflowed: grew without bound
  return MaxOver(tr, T - 50.0, T) / MaxOver(tr, T / 2 - 50.0, T / 2);
}

TEST(DelayMargin, TopologiesCoverComplexAndDefectiveH) {
  const auto cases = Cases();
  // ring3 and ring4: the critical eigenvalue is complex.
  for (int k : {1, 2}) {
    const auto d =
        theory::ComputeDelayMargin(theory::HEigenvalues(cases[k].H), cases[k].k1, cases[k].k2);
    ASSERT_GE(d.critical, 0);
    EXPECT_GT(std::abs(d.per_eigenvalue[d.critical].lambda.imag()), 0.5) << cases[k].name;
  }
  // chain3: eigenvalue 1 three times, but H - I has rank 2 (one eigenvector only).
  const Eigen::MatrixXd N = cases[3].H - Eigen::MatrixXd::Identity(3, 3);
  EXPECT_EQ(Eigen::FullPivLU<Eigen::MatrixXd>(N).rank(), 2);
  EXPECT_GT((N * N).cwiseAbs().maxCoeff(), 0.5);  // N^2 != 0: a single 3x3 Jordan block
}

// Stable at 0.95x the margin (the error decays by > 10x between late windows), unstable at
// 1.05x (it grows by > 10x). Measured rates are around 1e-2..1e-6 and 1e2..1e7.
TEST(DelayMargin, TimeDomainAgreesOnEveryTopology) {
  for (const Case& c : Cases()) {
    const auto d = theory::ComputeDelayMargin(theory::HEigenvalues(c.H), c.k1, c.k2);
    ASSERT_TRUE(d.stable_at_zero) << c.name;
    ASSERT_GT(d.tau_s, 0.0) << c.name;
    const double below = LateGrowth(c, 0.95 * d.tau_s);
    const double above = LateGrowth(c, 1.05 * d.tau_s);
    EXPECT_LT(below, 0.1) << c.name << " margin " << d.tau_s;
    EXPECT_GT(above, 10.0) << c.name << " margin " << d.tau_s;
  }
}

// The delayed simulator itself: with tau = 0 it reproduces the matrix exponential of the
// undelayed loop, and a defective H is simulated like any other.
TEST(DelayMargin, UndelayedSimulationMatchesMatrixExponential) {
  const Eigen::MatrixXd H = Cases()[1].H;  // complex eigenvalues
  const double k1 = 0.5, k2 = 1.0;
  const int n = 3;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(2 * n, 2 * n);
  A.topRightCorner(n, n).setIdentity();
  A.bottomLeftCorner(n, n) = -k1 * H;
  A.bottomRightCorner(n, n) = -k2 * H;
  Eigen::VectorXd x0(n), v0(n), e0(2 * n);
  x0 << 1.0, -2.0, 0.5;
  v0 << 0.0, 0.3, -0.1;
  e0 << x0, v0;
  const double t = 5.0;
  // exp(A t) e0 by many small Taylor-series steps (independent of the simulator's RK4).
  Eigen::VectorXd e = e0;
  const int steps = 5000;
  const double h = t / steps;
  for (int s = 0; s < steps; ++s) {
    Eigen::VectorXd term = e, sum = e;
    for (int k = 1; k < 12; ++k) {
      term = A * term * (h / k);
      sum += term;
    }
    e = sum;
  }
  const DelayedLinearTrace tr = SimulateDelayedConsensus(H, k1, k2, 0.0, x0, v0, t, 1e-3, t);
  EXPECT_NEAR(tr.error_norm.back(), e.norm(), 1e-9);
}

// A delay equal to one step and one of many steps give the same trajectory for the same
// tau: the history buffer handles N = 1 and large N alike (the step is tau / N).
TEST(DelayMargin, DelayedSimulationConvergesInStepSize) {
  const Eigen::MatrixXd H = Cases()[0].H;
  const Eigen::VectorXd x0 = Eigen::VectorXd::LinSpaced(5, 1.0, 2.0);
  const Eigen::VectorXd v0 = Eigen::VectorXd::LinSpaced(5, -0.5, 0.5);
  const double tau = 0.2;
  const auto a = SimulateDelayedConsensus(H, 0.18, 1.152, tau, x0, v0, 20.0, tau, 20.0);
  const auto b = SimulateDelayedConsensus(H, 0.18, 1.152, tau, x0, v0, 20.0, 1e-3, 20.0);
  const auto c = SimulateDelayedConsensus(H, 0.18, 1.152, tau, x0, v0, 20.0, 5e-4, 20.0);
  EXPECT_NEAR(b.error_norm.back(), c.error_norm.back(), 1e-12);
  EXPECT_NEAR(a.error_norm.back(), c.error_norm.back(), 1e-7);
}

}  // namespace
}  // namespace shoal

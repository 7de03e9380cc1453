// core/theory: the paper's printed numbers (Sec. IV, Example 1), the algebra behind them,
// and the exact delay margin's defining properties.
#include "core/theory.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "core/disturbance.h"
#include "core/topology.h"

namespace shoal {
namespace theory {
namespace {

// The paper's topology (Fig. 1): L and D as printed in Sec. IV.
Eigen::MatrixXd PaperH() {
  Eigen::MatrixXd L(5, 5), D = Eigen::MatrixXd::Zero(5, 5);
  L << 1, 0, -1, 0, 0,  //
      -1, 2, 0, 0, -1,  //
      -1, 0, 1, 0, 0,   //
      0, 0, 0, 1, -1,   //
      0, -1, 0, -1, 2;
  D(0, 0) = D(2, 2) = D(4, 4) = 1.0;
  return L + D;
}

std::vector<double> Sorted(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v;
}

// Given the paper's L and D, the printed W (Sec. IV) is reproduced to its 4 decimals.
TEST(Theory, PaperWAsPrinted) {
  Eigen::MatrixXd printed(5, 5);
  printed << 0.4052, 0.1128, 0.1976, 0.0972, 0.0818,  //
      0.1128, 0.3333, 0.0363, 0.1667, 0.1667,         //
      0.1976, 0.0363, 0.3488, 0.0431, 0.0322,         //
      0.0972, 0.1667, 0.0431, 0.8333, 0.3333,         //
      0.0818, 0.1667, 0.0322, 0.3333, 0.3333;
  const auto W = SolveW(PaperH());
  ASSERT_TRUE(W.has_value());
  for (int i = 0; i < 5; ++i) {
    for (int j = 0; j < 5; ++j) EXPECT_NEAR((*W)(i, j), printed(i, j), 1e-4) << i << "," << j;
  }
}

// The printed eig(W) = 1.1167, 0.5506, 0.1650, 0.1278, 0.2940 and, with alpha = 0.05,
// beta = 6.4, eig(M^2) = 0.0168, 0.2766, 0.2372, 0.2038, 0.1258 (all real).
TEST(Theory, PaperEigenvaluesOfWAndM2AsPrinted) {
  const auto t = ComputeTheorem1(PaperH(), 0.18, 1.152, 0.05, 6.4);
  ASSERT_TRUE(t.has_value());
  const std::vector<double> w_printed = Sorted({1.1167, 0.5506, 0.1650, 0.1278, 0.2940});
  std::vector<double> w(t->W_eigenvalues.data(), t->W_eigenvalues.data() + 5);
  w = Sorted(w);
  for (int i = 0; i < 5; ++i) EXPECT_NEAR(w[i], w_printed[i], 1e-4) << i;

  const std::vector<double> m2_printed = Sorted({0.0168, 0.2766, 0.2372, 0.2038, 0.1258});
  std::vector<double> m2;
  for (const Complex& c : t->M2_eigenvalues) {
    EXPECT_NEAR(c.imag(), 0.0, 1e-12);
    m2.push_back(c.real());
  }
  m2 = Sorted(m2);
  for (int i = 0; i < 5; ++i) EXPECT_NEAR(m2[i], m2_printed[i], 1e-4) << i;
  EXPECT_NEAR(t->lambda_max_M2, 0.2766, 1e-4);
}

// H's eigenvalues as docs/reference.md lists them (3.879, 3, 1.653, 1, 0.468).
TEST(Theory, PaperHEigenvalues) {
  const auto ev = HEigenvalues(PaperH());
  const double expect[] = {3.879, 3.0, 1.653, 1.0, 0.468};
  ASSERT_EQ(ev.size(), 5u);
  for (int i = 0; i < 5; ++i) {
    EXPECT_NEAR(ev[i].real(), expect[i], 1e-3);
    EXPECT_NEAR(ev[i].imag(), 0.0, 1e-9);
  }
}

// W solves the Lyapunov equation and is symmetric positive definite, also for a random
// strongly connected pinned topology with complex eigenvalues.
TEST(Theory, WSolvesLyapunovEquation) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    const int n = 3 + trial % 6;
    std::vector<std::pair<int, int>> edges;
    for (int i = 1; i <= n; ++i) edges.emplace_back(i, i % n + 1);  // a directed ring
    for (int i = 1; i <= n; ++i) {
      for (int j = 1; j <= n; ++j) {
        if (i != j && j != i % n + 1 && u(rng) < 0.2) edges.emplace_back(i, j);
      }
    }
    const Topology topo = Topology::Build(n, edges, {1});
    const Eigen::MatrixXd H = topo.H();
    const auto W = SolveW(H);
    ASSERT_TRUE(W.has_value());
    const Eigen::MatrixXd R = *W * H + H.transpose() * *W - Eigen::MatrixXd::Identity(n, n);
    EXPECT_LT(R.cwiseAbs().maxCoeff(), 1e-10) << trial;
    EXPECT_LT((*W - W->transpose()).cwiseAbs().maxCoeff(), 1e-12);
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(*W);
    EXPECT_GT(es.eigenvalues().minCoeff(), 0.0);
  }
}

TEST(Theory, NoWWhenHHasAnEigenvalueWithNonPositiveRealPart) {
  // Follower 2 unreachable: H = [[1, 0], [0, 0]] has eigenvalue 0.
  const Topology topo = Topology::Build(2, {}, {1});
  EXPECT_FALSE(SolveW(topo.H()).has_value());
  EXPECT_FALSE(ComputeTheorem1(topo.H(), 1.0, 1.0, 0.05, 6.4).has_value());
}

// The figures docs/examples.md quotes for the scenario gains: the paper's bound 0.1286, the corrected
// 0.1754 (lambda_max(M^T M) = 0.2882), P's largest eigenvalue -7.3e-4.
TEST(Theory, Theorem1BoundsForPaperExample) {
  const auto t = ComputeTheorem1(PaperH(), 0.18, 1.152, 0.05, 6.4);
  ASSERT_TRUE(t.has_value());
  ASSERT_TRUE(t->k1_min && t->k1_min_corrected);
  EXPECT_NEAR(*t->k1_min, 0.1286, 1e-4);
  EXPECT_NEAR(*t->k2_min, 6.4 * *t->k1_min, 1e-12);
  EXPECT_NEAR(t->lambda_max_MtM, 0.2882, 1e-4);
  EXPECT_NEAR(*t->k1_min_corrected, 0.1754, 1e-4);
  EXPECT_NEAR(t->P_max_eigenvalue, -7.3e-4, 0.05e-4);
  EXPECT_TRUE(t->Q_positive_definite);
  EXPECT_TRUE(t->certifies);
  // lambda_max(M^T M) >= lambda_max(M^2) always (spectral radius <= norm).
  EXPECT_GE(t->lambda_max_MtM, t->lambda_max_M2);
}

// P matches the paper's closed form (18) when k2 = beta k1, and the corrected bound is the
// threshold of the Schur argument: above it P < 0.
TEST(Theory, PMatchesEquation18AndCorrectedBoundIsSufficient) {
  const double alpha = 0.05, beta = 6.4;
  const Eigen::MatrixXd H = PaperH();
  const auto base = ComputeTheorem1(H, 1.0, beta, alpha, beta);
  ASSERT_TRUE(base.has_value());
  for (double k1 : {0.05, 0.18, 0.5, 2.0}) {
    const auto t = ComputeTheorem1(H, k1, beta * k1, alpha, beta);
    ASSERT_TRUE(t.has_value());
    const int n = 5;
    Eigen::MatrixXd P18(2 * n, 2 * n);
    P18 << -k1 * alpha * Eigen::MatrixXd::Identity(n, n), k1 * t->M, k1 * t->M.transpose(),
        2 * alpha * t->W - k1 * beta * Eigen::MatrixXd::Identity(n, n);
    EXPECT_LT((t->P - P18).cwiseAbs().maxCoeff(), 1e-12) << k1;
    if (k1 > *base->k1_min_corrected) {
      EXPECT_LT(t->P_max_eigenvalue, 0.0) << k1;
    }
  }
}

TEST(Theory, Theorem1BoundEmptyWhenAlphaBetaTooSmall) {
  // alpha beta = 0.05 * 1 = 0.05 < lambda_max(M^2) for this H: (15) has no solution.
  const auto t = ComputeTheorem1(PaperH(), 0.18, 0.18, 0.05, 1.0);
  ASSERT_TRUE(t.has_value());
  EXPECT_LT(0.05, t->lambda_max_M2);
  EXPECT_FALSE(t->k1_min.has_value());
  EXPECT_FALSE(t->k2_min.has_value());
}

// Theorem 2 with the printed formulas, and the corrected ones doubling the rho0 terms, on
// a topology where (21)'s denominators are positive (every follower hears the leader).
TEST(Theory, Theorem2Formulas) {
  const double alpha = 0.2, beta = 4.0, rho0 = 0.01;
  const Eigen::MatrixXd H = Topology::Build(3, {}, {1, 2, 3}).H();  // H = I
  const auto t1 = ComputeTheorem1(H, 3.0, 12.0, alpha, beta);
  ASSERT_TRUE(t1.has_value());
  const Theorem2 t = ComputeTheorem2(*t1, alpha, beta, rho0);
  const double lw = t1->lambda_max_W;
  EXPECT_NEAR(t.k11, (3 * alpha + 1) * rho0 * lw / alpha, 1e-12);
  EXPECT_NEAR(t.k11_corrected, 2 * t.k11, 1e-12);
  ASSERT_TRUE(t.k12.has_value());
  EXPECT_NEAR(*t.k12,
              (2 * alpha * alpha * lw + alpha * (alpha + 3) / 2 * rho0 * lw) /
                  (alpha * beta - 2 * t1->lambda_max_M2),
              1e-12);
  ASSERT_TRUE(t.k12_corrected.has_value());
  EXPECT_GE(*t.k12_corrected, *t.k12);
  EXPECT_NEAR(*t.k22, beta * *t.k12, 1e-12);
  // rho0 = 0: P~ = P.
  const Theorem2 t0 = ComputeTheorem2(*t1, alpha, beta, 0.0);
  EXPECT_NEAR(t0.P_tilde_max_eigenvalue, t1->P_max_eigenvalue, 1e-12);
  // A larger rho0 never helps.
  EXPECT_GE(t.P_tilde_max_eigenvalue, t0.P_tilde_max_eigenvalue);
}

// On the paper's topology the denominators of (21), alpha beta - 2 lambda_max(M^2) (and
// with M^T M), are negative for every alpha beta: Theorem 2's bounds give no gains at all.
TEST(Theory, Theorem2PaperTopologyHasNoBoundForAnyAlphaBeta) {
  for (double ab = 0.01; ab < 50.0; ab *= 1.1) {
    const auto t1 = ComputeTheorem1(PaperH(), 0.18, 1.152, 0.05, ab / 0.05);
    ASSERT_TRUE(t1.has_value());
    EXPECT_LT(ab - 2.0 * t1->lambda_max_M2, 0.0) << ab;
    const Theorem2 t = ComputeTheorem2(*t1, 0.05, ab / 0.05, 0.5);
    EXPECT_FALSE(t.k12.has_value());
    EXPECT_FALSE(t.k1_min_corrected.has_value());
  }
  const auto t1 = ComputeTheorem1(PaperH(), 0.18, 1.152, 0.05, 6.4);
  EXPECT_FALSE(ComputeTheorem2(*t1, 0.05, 6.4, 0.5).certifies);
}

// The paper's lambda_max(G^2) = 0.0004 and lambda_max(J^2) = 0.25, and the Lipschitz
// inequality of Assumption 2 holds for F~ at random pairs of points.
TEST(Theory, PaperExample2LipschitzData) {
  DisturbanceConfig d;
  d.kind = DisturbanceKind::kPaperExample2;
  const Lipschitz l = LipschitzOf(d);
  EXPECT_TRUE(l.applicable);
  EXPECT_NEAR(l.lambda_max_G2, 0.0004, 1e-15);
  EXPECT_NEAR(l.lambda_max_J2, 0.25, 1e-15);
  EXPECT_NEAR(l.rho0, 0.5, 1e-15);
  const double g = std::sqrt(l.lambda_max_G2), j = std::sqrt(l.lambda_max_J2);
  std::mt19937 rng(3);
  std::normal_distribution<double> nd(0.0, 2.0);
  for (int k = 0; k < 2000; ++k) {
    Vec5 x1, v1, x2, v2;
    for (int c = 0; c < 5; ++c) {
      x1(c) = nd(rng), v1(c) = nd(rng);
      x2(c) = x1(c) + 0.1 * nd(rng), v2(c) = v1(c) + 0.1 * nd(rng);
    }
    const double lhs = (PaperExample2F(x1, v1) - PaperExample2F(x2, v2)).norm();
    EXPECT_LE(lhs, g * (x1 - x2).norm() + j * (v1 - v2).norm() + 1e-15);
  }
  // The slopes are attained: near the origin in v1 the ratio tends to J's largest entry 0.5.
  Vec5 z = Vec5::Zero(), dv = Vec5::Zero();
  dv(4) = 1e-6;
  EXPECT_NEAR((PaperExample2F(z, dv) - PaperExample2F(z, z)).norm() / 1e-6, 0.5, 1e-6);

  d.relative_to_leader = false;
  EXPECT_FALSE(LipschitzOf(d).applicable);
  d.kind = DisturbanceKind::kOceanCurrent;
  EXPECT_FALSE(LipschitzOf(d).applicable);
  d.kind = DisturbanceKind::kNone;
  EXPECT_EQ(LipschitzOf(d).rho0, 0.0);
}

TEST(Theory, DelayBoundsPerModel) {
  DelayConfig c;
  EXPECT_EQ(DelayBoundsOf(c).h_s, 0.0);
  c.kind = DelayKind::kConstant;
  c.base_s = 0.2;
  EXPECT_EQ(DelayBoundsOf(c).h_s, 0.2);
  EXPECT_EQ(*DelayBoundsOf(c).kappa, 0.0);
  EXPECT_TRUE(DelayBoundsOf(c).constant);
  c.kind = DelayKind::kSinusoid;
  c.base_s = 0.1, c.amplitude_s = 0.05, c.omega_rad_s = 1.0;
  EXPECT_NEAR(DelayBoundsOf(c).h_s, 0.15, 1e-15);
  EXPECT_NEAR(*DelayBoundsOf(c).kappa, 0.05, 1e-15);
  EXPECT_TRUE(DelayBoundsOf(c).time_varying);
  c.kind = DelayKind::kUniform;
  EXPECT_NEAR(DelayBoundsOf(c).h_s, 0.15, 1e-15);
  EXPECT_FALSE(DelayBoundsOf(c).kappa.has_value());
}

TEST(Theory, DelayBoundsOfScenarioTakesMaxOverLinks) {
  Scenario s;
  s.followers = 3;
  s.edges = {{2, 1}, {3, 2}};
  s.leader_links = {1};
  s.delay.kind = DelayKind::kConstant;
  s.delay.base_s = 0.1;
  DelayBounds b = DelayBoundsOf(s);
  EXPECT_NEAR(b.h_s, 0.1, 1e-15);
  EXPECT_TRUE(b.constant);
  LinkOverride o;
  o.from = 2, o.to = 3;
  o.delay = DelayConfig{DelayKind::kSinusoid, 0.2, 0.1, 2.0};
  s.links.push_back(o);
  b = DelayBoundsOf(s);
  EXPECT_NEAR(b.h_s, 0.3, 1e-15);
  EXPECT_NEAR(*b.kappa, 0.2, 1e-15);
  EXPECT_FALSE(b.constant);
  // A link override on a link that is not in the topology changes nothing.
  s.links[0].from = 1;
  s.links[0].to = 3;
  b = DelayBoundsOf(s);
  EXPECT_NEAR(b.h_s, 0.1, 1e-15);
  // Two different constant delays: bounded, but not one common constant.
  s.links[0] = o;
  s.links[0].delay = DelayConfig{DelayKind::kConstant, 0.05, 0, 0};
  b = DelayBoundsOf(s);
  EXPECT_NEAR(b.h_s, 0.1, 1e-15);
  EXPECT_FALSE(b.constant);
  EXPECT_FALSE(b.time_varying);
}

// The margin of the paper example's largest eigenvalue, by hand: w^2 solves
// u^2 - |l|^2 k2^2 u - |l|^2 k1^2 = 0 and tau = atan2(k2 w, k1) / w (docs/examples.md: 0.34 s).
TEST(Theory, DelayMarginRealEigenvalueClosedForm) {
  const double k1 = 0.18, k2 = 1.152;
  const DelayMargin d = ComputeDelayMargin(HEigenvalues(PaperH()), k1, k2);
  ASSERT_TRUE(d.stable_at_zero);
  ASSERT_EQ(d.critical, 0);  // the largest eigenvalue, 3.879
  const double l = d.per_eigenvalue[0].lambda.real();
  const double a = l * l * k2 * k2, b = l * l * k1 * k1;
  const double w = std::sqrt((a + std::sqrt(a * a + 4 * b)) / 2);
  EXPECT_NEAR(std::abs(d.per_eigenvalue[0].omega_rad_s), w, 1e-12);
  EXPECT_NEAR(d.tau_s, std::atan2(k2 * w, k1) / w, 1e-12);
  EXPECT_NEAR(d.tau_s, 0.343, 1e-3);
}

// At (tau_s, j omega) the characteristic function vanishes, for real, complex and
// conjugate eigenvalues; every crossing moves into the right half plane.
// s^2 + k2 s + k1 with k1 = 1e-6, k2 = 1e6: roots near -1e6 and -1e-12, both stable. The
// textbook formula loses the small one to cancellation and calls the loop unstable.
TEST(Theory, AStableLoopWithGainsFarApartIsStable) {
  EXPECT_TRUE(EigenDelayMargin(Complex(1.0, 0.0), 1e-6, 1e6).stable_at_zero);
  EXPECT_TRUE(GeneralDelayMargin(Complex(1e6, 0.0), Complex(1e-6, 0.0)).stable_at_zero);
  EXPECT_FALSE(EigenDelayMargin(Complex(-1.0, 0.0), 1e-6, 1e6).stable_at_zero);
  EXPECT_FALSE(GeneralDelayMargin(Complex(1e6, 0.0), Complex(0.0, 0.0)).stable_at_zero);
}

TEST(Theory, DelayMarginIsARootOnTheImaginaryAxis) {
  for (const Complex l : {Complex(2.0, 0.0), Complex(1.5, 0.866), Complex(1.5, -0.866),
                          Complex(0.3, 2.0), Complex(5.0, -0.1)}) {
    for (const auto& [k1, k2] :
         {std::pair{0.18, 1.152}, std::pair{1.0, 2.0}, std::pair{0.02, 0.5}}) {
      const EigenMargin m = EigenDelayMargin(l, k1, k2);
      if (!m.stable_at_zero) continue;
      const Complex s(0.0, m.omega_rad_s);
      const Complex F = s * s + l * (k2 * s + k1) * std::exp(-s * m.tau_s);
      EXPECT_LT(std::abs(F), 1e-10) << l << " " << k1 << " " << k2;
      EXPECT_GT(m.tau_s, 0.0);
      EXPECT_GT(m.crossing_direction, 0.0);
    }
  }
}

// A conjugate pair has the same margin (the roots of one are the conjugates of the other).
TEST(Theory, ConjugateEigenvaluesShareTheirMargin) {
  const EigenMargin a = EigenDelayMargin(Complex(1.2, 0.7), 0.5, 1.5);
  const EigenMargin b = EigenDelayMargin(Complex(1.2, -0.7), 0.5, 1.5);
  EXPECT_NEAR(a.tau_s, b.tau_s, 1e-12);
  EXPECT_NEAR(a.omega_rad_s, -b.omega_rad_s, 1e-12);
}

// Complex lambda can be unstable without delay: s^2 + lambda (k2 s + k1) has a root in
// Re s > 0 when k1 is large against k2^2 (Im lambda)^2 / Re lambda-type terms.
TEST(Theory, ComplexEigenvalueCanBeUnstableAtZeroDelay) {
  const Complex l(0.2, 3.0);
  EXPECT_FALSE(EigenDelayMargin(l, 10.0, 0.1).stable_at_zero);
  EXPECT_TRUE(EigenDelayMargin(l, 0.1, 10.0).stable_at_zero);
  const DelayMargin d = ComputeDelayMargin({Complex(1.0, 0.0), l, std::conj(l)}, 10.0, 0.1);
  EXPECT_FALSE(d.stable_at_zero);
  EXPECT_EQ(d.tau_s, 0.0);
}

// Scaling k1 -> c^2 k1, k2 -> c k2 divides the margin by c exactly (s -> c s, tau -> tau/c).
TEST(Theory, DelayMarginScalingLaw) {
  const auto ev = HEigenvalues(PaperH());
  const double m = ComputeDelayMargin(ev, 0.18, 1.152).tau_s;
  for (double c : {0.5, 2.0, 3.7}) {
    EXPECT_NEAR(ComputeDelayMargin(ev, c * c * 0.18, c * 1.152).tau_s, m / c, 1e-12) << c;
  }
}

// The general form s^2 + (a s + b) e^{-s tau} reduces to the eigenvalue form, and its
// margin is a root on the imaginary axis for arbitrary complex a, b.
TEST(Theory, GeneralDelayMarginAgreesAndIsARoot) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int checked = 0;
  for (int k = 0; k < 200; ++k) {
    const Complex l(2.0 + 2.0 * u(rng), 1.5 * u(rng));
    const double k1 = 0.5 + 0.5 * u(rng), k2 = 1.0 + 0.8 * u(rng);
    const EigenMargin e = EigenDelayMargin(l, k1, k2);
    const EigenMargin g = GeneralDelayMargin(l * k2, l * k1);
    ASSERT_EQ(e.stable_at_zero, g.stable_at_zero);
    if (!e.stable_at_zero) continue;
    EXPECT_NEAR(g.tau_s, e.tau_s, 1e-9 * e.tau_s) << l;
    const Complex a(1.0 + u(rng), u(rng)), b(1.0 + u(rng), u(rng));
    const EigenMargin m = GeneralDelayMargin(a, b);
    if (!m.stable_at_zero || !std::isfinite(m.tau_s)) continue;
    const Complex s(0.0, m.omega_rad_s);
    EXPECT_LT(std::abs(s * s + (a * s + b) * std::exp(-s * m.tau_s)), 1e-9) << a << b;
    ++checked;
  }
  EXPECT_GT(checked, 50);
}

// Example 2's factor: -0.5 tanh(psi') adds delayed damping to the heading channel, which
// lowers the margin of the largest eigenvalue (0.3435 s -> about 0.31 s); 0.48 tanh(theta')
// removes damping from pitch, which makes k2 = 1.0 unstable without any delay
// (lambda_min k2 = 0.468 < 0.48), as shoal sim shows (docs/theory.md).
TEST(Theory, FactorDelayMarginOfPaperExample2) {
  DisturbanceConfig d;
  d.kind = DisturbanceKind::kPaperExample2;
  const Lipschitz l = LipschitzOf(d);
  const auto ev = HEigenvalues(PaperH());
  const FactorDelayMargin f = ComputeFactorDelayMargin(ev, 0.18, 1.152, l);
  ASSERT_TRUE(f.available);
  ASSERT_TRUE(f.stable_at_zero);
  EXPECT_EQ(f.component, 4);  // heading
  EXPECT_NEAR(f.v_slope, -0.5, 1e-15);
  EXPECT_NEAR(f.lambda.real(), 3.8794, 1e-4);
  EXPECT_LT(f.tau_s, ComputeDelayMargin(ev, 0.18, 1.152).tau_s);
  EXPECT_NEAR(f.tau_s, 0.31, 0.01);
  EXPECT_FALSE(ComputeFactorDelayMargin(ev, 0.18, 1.0, l).stable_at_zero);
  // No factor: the same as the nominal margin.
  d.kind = DisturbanceKind::kNone;
  EXPECT_NEAR(ComputeFactorDelayMargin(ev, 0.18, 1.152, LipschitzOf(d)).tau_s,
              ComputeDelayMargin(ev, 0.18, 1.152).tau_s, 1e-9);
  d.kind = DisturbanceKind::kOceanCurrent;
  EXPECT_FALSE(ComputeFactorDelayMargin(ev, 0.18, 1.152, LipschitzOf(d)).available);
}

}  // namespace
}  // namespace theory
}  // namespace shoal

// Property tests of core/fossen: the REMUS 100 model's structure (M, C(nu), J(eta)) and
// the RK4 integrator. Random states come from a seeded shoal::Rng, so every run checks
// the same states on every platform.
#include "core/fossen.h"
#include "core/control.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include "core/rng.h"

namespace shoal {
namespace {

constexpr double kPiD = 3.14159265358979323846;

double U(Rng* rng, double lo, double hi) { return lo + (hi - lo) * rng->Uniform(); }

/// eta with positions in [-50, 50] m, |theta| < max_theta, psi in [-pi, pi).
Vec5 RandomEta(Rng* rng, double max_theta) {
  Vec5 eta;
  eta << U(rng, -50, 50), U(rng, -50, 50), U(rng, -50, 50), U(rng, -max_theta, max_theta),
      U(rng, -kPiD, kPiD);
  return eta;
}

/// nu with |[u v w]| <= max_speed (random direction) and |q|, |r| <= max_rate.
Vec5 RandomNu(Rng* rng, double max_speed, double max_rate) {
  Vec3 dir(rng->Normal(), rng->Normal(), rng->Normal());
  dir.normalize();
  const double speed = max_speed * rng->Uniform();
  Vec5 nu;
  nu.head<3>() = speed * dir;
  nu(3) = U(rng, -max_rate, max_rate);
  nu(4) = U(rng, -max_rate, max_rate);
  return nu;
}

/// Max-norm distance of two plant states.
double StateDistance(const PlantState& a, const PlantState& b) {
  return std::max((a.eta - b.eta).cwiseAbs().maxCoeff(), (a.nu - b.nu).cwiseAbs().maxCoeff());
}

// ---------------------------------------------------------------------------------------
// C(nu)

TEST(FossenCoriolisTest, SkewSymmetricAtRandomStates) {
  const FossenModel model;
  Rng rng(20240101);
  for (int k = 0; k < 2000; ++k) {
    // Given a random body velocity (including ones beyond the vehicle's envelope).
    const Vec5 nu = RandomNu(&rng, 5.0, 2.0);
    // When C(nu) is formed.
    const Mat5 C = model.C(nu);
    // Then C + C^T = 0 and nu^T C nu = 0 (C does no work).
    const double scale = C.norm() + 1e-300;
    ASSERT_LE((C + C.transpose()).norm(), 1e-12 * scale) << "k=" << k << " nu=" << nu.transpose();
    ASSERT_LE(std::abs(nu.dot(C * nu)), 1e-12 * scale * nu.squaredNorm())
        << "k=" << k << " nu=" << nu.transpose();
    // And the work against an arbitrary other velocity is antisymmetric: x^T C y = -y^T C x.
    const Vec5 x = RandomNu(&rng, 3.0, 1.0);
    ASSERT_NEAR(x.dot(C * nu), -nu.dot(C * x), 1e-12 * scale * x.norm() * nu.norm());
  }
}

TEST(FossenCoriolisTest, NonTrivialForNonZeroVelocity) {
  // Guards the skew test against C == 0: every velocity component enters C.
  const FossenModel model;
  for (int i = 0; i < 5; ++i) {
    Vec5 nu = Vec5::Zero();
    nu(i) = 1.0;
    EXPECT_GT(model.C(nu).norm(), 1.0) << "component " << i;
  }
  EXPECT_EQ(model.C(Vec5(Vec5::Zero())).norm(), 0.0);
}

TEST(FossenCoriolisTest, AgreesWithFossenTheoremOnEmbedded6DofMassMatrix) {
  // Independent formulation (Fossen 2011, Thm. 3.2): for M = M^T > 0,
  //   C(nu) = [[0, -S(M11 nu1 + M12 nu2)], [-S(M11 nu1 + M12 nu2), -S(M21 nu1 + M22 nu2)]]
  // with nu1 = [u v w], nu2 = [p q r]. The 5-DOF C is this with p = 0 and the roll
  // row/column removed.
  const FossenModel model;
  const Mat5& M5 = model.M();
  // Embed M into 6-DOF, index map 5-DOF [u v w q r] -> 6-DOF [u v w p q r].
  const int map[5] = {0, 1, 2, 4, 5};
  Eigen::Matrix<double, 6, 6> M6 = Eigen::Matrix<double, 6, 6>::Zero();
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 5; ++j) M6(map[i], map[j]) = M5(i, j);
  M6(3, 3) = 1.0;  // roll inertia: any value, p = 0.
  auto S = [](const Vec3& x) {
    Mat3 s;
    s << 0, -x(2), x(1), x(2), 0, -x(0), -x(1), x(0), 0;
    return s;
  };
  Rng rng(77);
  for (int k = 0; k < 1000; ++k) {
    const Vec5 nu = RandomNu(&rng, 3.0, 1.5);
    Eigen::Matrix<double, 6, 1> nu6 = Eigen::Matrix<double, 6, 1>::Zero();
    for (int i = 0; i < 5; ++i) nu6(map[i]) = nu(i);
    const Vec3 a1 = M6.topLeftCorner<3, 3>() * nu6.head<3>() +
                    M6.topRightCorner<3, 3>() * nu6.tail<3>();
    const Vec3 a2 = M6.bottomLeftCorner<3, 3>() * nu6.head<3>() +
                    M6.bottomRightCorner<3, 3>() * nu6.tail<3>();
    Eigen::Matrix<double, 6, 6> C6 = Eigen::Matrix<double, 6, 6>::Zero();
    C6.topRightCorner<3, 3>() = -S(a1);
    C6.bottomLeftCorner<3, 3>() = -S(a1);
    C6.bottomRightCorner<3, 3>() = -S(a2);
    Mat5 expected;
    for (int i = 0; i < 5; ++i)
      for (int j = 0; j < 5; ++j) expected(i, j) = C6(map[i], map[j]);
    const Mat5 C = model.C(nu);
    ASSERT_LE((C - expected).norm(), 1e-12 * (1.0 + expected.norm()))
        << "k=" << k << "\nC=\n" << C << "\nexpected=\n" << expected;
  }
}

TEST(FossenCoriolisTest, CoriolisForceEqualsCTimesNu) {
  // The written-out C(nu) nu used by the dynamics is the matrix product.
  const FossenModel model;
  Rng rng(78);
  for (int k = 0; k < 2000; ++k) {
    const Vec5 nu = RandomNu(&rng, 4.0, 2.0);
    const Vec5 expected = model.C(nu) * nu;
    const Vec5 got = model.CoriolisForce(nu);
    ASSERT_LE((got - expected).cwiseAbs().maxCoeff(),
              1e-12 * (1.0 + model.C(nu).norm() * nu.norm()))
        << "k=" << k << " nu=" << nu.transpose();
    // And it does no work.
    ASSERT_LE(std::abs(nu.dot(got)), 1e-12 * (1.0 + model.C(nu).norm() * nu.squaredNorm()));
  }
}

// ---------------------------------------------------------------------------------------
// M

TEST(FossenMassTest, MatchesReferenceValues) {
  const Mat5 M = MassMatrix(RemusParams());
  // docs/reference.md "Mass matrix (derived)"; 1-based names m_ij -> M(i-1, j-1).
  Mat5 expected = Mat5::Zero();
  expected(0, 0) = 31.41;
  expected(1, 1) = 65.98;
  expected(2, 2) = 65.98;
  expected(3, 3) = 8.33;
  expected(4, 4) = 8.33;
  expected(1, 4) = -1.93;  // m25
  expected(4, 1) = -1.93;  // m52
  expected(2, 3) = +1.93;  // m34
  expected(3, 2) = +1.93;  // m43
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 5; ++j)
      EXPECT_NEAR(M(i, j), expected(i, j), 1e-12) << "m" << i + 1 << j + 1;
  // The model holds the same matrix.
  EXPECT_EQ(FossenModel().M(), M);
}

TEST(FossenMassTest, SymmetricPositiveDefinite) {
  const FossenModel model;
  const Mat5& M = model.M();
  EXPECT_EQ(M, M.transpose());
  Eigen::LLT<Mat5> llt(M);
  EXPECT_EQ(llt.info(), Eigen::Success);
  Eigen::SelfAdjointEigenSolver<Mat5> eig(M);
  ASSERT_EQ(eig.info(), Eigen::Success);
  EXPECT_GT(eig.eigenvalues().minCoeff(), 1.0);
  EXPECT_LE((model.M_inv() * M - Mat5::Identity()).norm(), 1e-14);
}

TEST(FossenMassTest, SolveMIsTheInverse) {
  const FossenModel model;
  Rng rng(79);
  for (int k = 0; k < 1000; ++k) {
    Vec5 x;
    for (int i = 0; i < 5; ++i) x(i) = U(&rng, -100, 100);
    const Vec5 y = model.SolveM(x);
    ASSERT_LE((model.M() * y - x).cwiseAbs().maxCoeff(), 1e-12 * (1.0 + x.norm())) << k;
    ASSERT_LE((y - model.M_inv() * x).cwiseAbs().maxCoeff(), 1e-13 * (1.0 + y.norm())) << k;
  }
}

TEST(FossenDynamicsTest, NuDotSatisfiesTheEquationOfMotion) {
  // M nu_dot + C(nu_r) nu_r + D(nu_r) nu_r + g(eta) = tau, nu_r = nu - nu_c, with the
  // full matrices (an independent assembly of the right-hand side).
  const FossenModel model;
  Rng rng(80);
  for (int k = 0; k < 2000; ++k) {
    const Vec5 eta = RandomEta(&rng, 1.2);
    const Vec5 nu = RandomNu(&rng, 2.5, 1.0);
    Vec5 tau;
    tau << U(&rng, -100, 100), U(&rng, -10, 10), U(&rng, -10, 10), U(&rng, -6, 6),
        U(&rng, -6, 6);
    const Vec3 current(U(&rng, -1, 1), U(&rng, -1, 1), U(&rng, -0.2, 0.2));
    const Vec5 nu_c = BodyCurrent(eta, current);
    // The current is the earth-frame velocity seen in the body frame, no rotation rate.
    ASSERT_LE((FossenModel::J(eta).topLeftCorner<3, 3>() * nu_c.head<3>() - current).norm(),
              1e-14);
    ASSERT_EQ(nu_c(3), 0.0);
    ASSERT_EQ(nu_c(4), 0.0);
    const Vec5 nu_dot = model.NuDot(eta, nu, tau, nu_c);
    const Vec5 nu_r = nu - nu_c;
    const Vec5 lhs = model.M() * nu_dot + model.C(nu_r) * nu_r + model.DampingForce(nu_r) +
                     model.Restoring(eta);
    ASSERT_LE((lhs - tau).cwiseAbs().maxCoeff(), 1e-10) << "k=" << k;
    ASSERT_EQ(model.NuDot(AttitudeTrig<double>(eta), nu, tau, nu_c), nu_dot);
  }
  // Damping opposes motion in every channel.
  for (int i = 0; i < 5; ++i) {
    Vec5 nu = Vec5::Zero();
    nu(i) = 0.7;
    EXPECT_GT(model.DampingForce(nu)(i), 0.0) << i;
    EXPECT_LT(model.DampingForce(Vec5(-nu))(i), 0.0) << i;
  }
}

// ---------------------------------------------------------------------------------------
// Damping: Prestero's nonlinear drag and lift (docs/reference.md, "Damping")

// Prestero's cruise: U = 1.54 m/s with propeller thrust X_prop = 3.86 N. In steady
// straight motion the surge drag must balance that thrust; counting his linearised X_u
// on top of the quadratic drag gives about 24 N instead.
constexpr double kCruiseSpeed = 1.54;   // m/s
constexpr double kCruiseThrust = 3.86;  // N

TEST(FossenDampingTest, CruiseDragBalancesPresteroThrust) {
  const FossenModel model;
  Vec5 nu = Vec5::Zero();
  nu(0) = kCruiseSpeed;
  EXPECT_NEAR(model.DampingForce(nu)(0), kCruiseThrust, 0.01 * kCruiseThrust);
  // Straight and level motion meets no other hydrodynamic force.
  EXPECT_EQ(model.DampingForce(nu).tail<4>().norm(), 0.0);
  // Starting from rest, that thrust alone settles the vehicle at Prestero's cruise speed
  // (surge time constant m11 / (2 |X_u|u|| U) = 6.3 s; 120 s is 19 of them).
  PlantState x;
  Vec5 tau = Vec5::Zero();
  tau(0) = kCruiseThrust;
  for (int k = 0; k < 6000; ++k) Integrate(model, tau, Vec3::Zero(), 0.02, 2, &x);
  EXPECT_NEAR(x.nu(0), kCruiseSpeed, 0.005 * kCruiseSpeed);
  EXPECT_LT(x.nu.tail<4>().cwiseAbs().maxCoeff(), 1e-12);
}

TEST(FossenDampingTest, LiftCoefficientsFollowPresteroGeometry) {
  // Prestero's body lift (-1/2 rho d^2 c_ydb, at the centre of pressure x_cp) and fin lift
  // (-1/2 rho c_La S_fin, at x_fin), with a force Z at body position x giving the moment
  // M = -x Z and a pitch rate q giving the heave velocity -x q there.
  const double rho = 1030.0, d = 0.191, c_ydb = 1.2, x_cp = -0.321;
  const double c_la = 3.12, s_fin = 0.00665, x_fin = -0.6827;
  const double z_uw_body = -0.5 * rho * d * d * c_ydb;
  const double z_uw_fin = -0.5 * rho * c_la * s_fin;
  const RemusParams p;
  const double tol = 5e-4;  // the parameters carry 4 significant digits
  EXPECT_NEAR(p.Z_uw, z_uw_body + z_uw_fin, tol * std::abs(p.Z_uw));
  EXPECT_NEAR(p.Z_uq, -x_fin * z_uw_fin, tol * std::abs(p.Z_uq));
  EXPECT_NEAR(p.M_uw, -x_cp * z_uw_body - x_fin * z_uw_fin, tol * std::abs(p.M_uw));
  EXPECT_NEAR(p.M_uq, x_fin * x_fin * z_uw_fin, tol * std::abs(p.M_uq));
  // Axisymmetry: (w, q, Z, M) -> (v, -r, Y, -N).
  EXPECT_EQ(p.Y_uv, p.Z_uw);
  EXPECT_EQ(p.Y_ur, -p.Z_uq);
  EXPECT_EQ(p.N_uv, -p.M_uw);
  EXPECT_EQ(p.N_ur, p.M_uq);
}

TEST(FossenDampingTest, LinearisationAtCruiseReproducesPresteroTable) {
  // Prestero's linear coefficients at U = 1.54 m/s are slopes of the nonlinear forces:
  //   Z_w = Z_wc + Z_uw U = -66.6 kg/s,   M_q = M_qc + M_uq U - Z_qdot U = -6.87 kg m^2/s,
  // Z_wc = -15.7 kg/s and M_qc = -2.16 kg m^2/s being his linearised cross-flow drag,
  // -Z_qdot U the added-mass term that C(nu) carries. The model's own slope of the
  // hydrodynamic force -(C(nu) nu + D(nu) nu), plus the cross-flow parts, must land on
  // his table: this ties the lift terms and C(nu) to the source.
  const FossenModel model;
  auto force = [&](const Vec5& nu) -> Vec5 {
    return -(model.CoriolisForce(nu) + model.DampingForce(nu));
  };
  Vec5 nu0 = Vec5::Zero();
  nu0(0) = kCruiseSpeed;
  const double h = 1e-6;
  auto slope = [&](int row, int col) {
    Vec5 dn = Vec5::Zero();
    dn(col) = h;
    return (force(Vec5(nu0 + dn))(row) - force(Vec5(nu0 - dn))(row)) / (2 * h);
  };
  const double z_wc = -15.7, m_qc = -2.16;
  EXPECT_NEAR(z_wc + slope(2, 2), -66.6, 0.01 * 66.6);  // Z_w
  EXPECT_NEAR(z_wc + slope(1, 1), -66.6, 0.01 * 66.6);  // Y_v (axisymmetry)
  EXPECT_NEAR(m_qc + slope(3, 3), -6.87, 0.01 * 6.87);  // M_q
  EXPECT_NEAR(m_qc + slope(4, 4), -6.87, 0.01 * 6.87);  // N_r (axisymmetry)
}

TEST(FossenDampingTest, DissipatesInForwardMotion) {
  // nu^T D(nu) nu >= 0 whenever u >= 0: the lift terms form a negative definite
  // quadratic form in (v, r) and in (w, q), times u. The surge drag is left out of the
  // sum (it is dissipative on its own and would hide a lift term of the wrong sign).
  const FossenModel model;
  Rng rng(81);
  for (int k = 0; k < 5000; ++k) {
    Vec5 nu = RandomNu(&rng, 3.0, 2.0);
    nu(0) = std::abs(nu(0));
    const Vec5 d = model.DampingForce(nu);
    ASSERT_GE(nu.tail<4>().dot(d.tail<4>()), 0.0) << "k=" << k << " nu=" << nu.transpose();
    ASSERT_GE(nu(0) * d(0), 0.0);
  }
}

// ---------------------------------------------------------------------------------------
// Energy

TEST(FossenEnergyTest, NeverIncreasesWithZeroInputInForwardMotion) {
  const FossenModel model;
  const Vec5 tau = Vec5::Zero();
  const Vec3 no_current = Vec3::Zero();
  Rng rng(4242);
  for (int trial = 0; trial < 200; ++trial) {
    // Given a random state moving forward (u in [0.5, 2.5] m/s, the lift terms describe
    // forward motion) with |theta| < 0.5 rad, some sway and heave, and turn and pitch
    // rates up to 0.3 rad/s (a REMUS 100 turns at about 0.2 rad/s).
    PlantState x;
    x.eta = RandomEta(&rng, 0.5);
    x.nu << U(&rng, 0.5, 2.5), U(&rng, -0.3, 0.3), U(&rng, -0.3, 0.3), U(&rng, -0.3, 0.3),
        U(&rng, -0.3, 0.3);
    const double e0 = model.Energy(x.eta, x.nu);
    ASSERT_GT(e0, 0.0);
    double e = e0;
    // When it coasts for up to 30 s (1500 control periods of 20 ms, two RK4 steps each),
    // as long as it still moves forward (the Munk moment turns a coasting vehicle, and
    // at low speed Coriolis coupling can carry u below zero).
    for (int k = 0; k < 1500; ++k) {
      Integrate(model, tau, no_current, 0.02, 2, &x);
      if (x.nu(0) < 0.0) break;
      const double e_next = model.Energy(x.eta, x.nu);
      // Then energy never increases.
      ASSERT_LE(e_next, e + 1e-9 * (1.0 + e)) << "trial " << trial << " step " << k;
      e = e_next;
    }
    // And damping removes a substantial part of it (quadratic drag alone takes a straight
    // u from 0.5 to 0.28 m/s in 30 s, kinetic energy to 31 %).
    EXPECT_LT(e, 0.5 * e0) << "trial " << trial;
  }
}

TEST(FossenEnergyTest, ConservedWithoutDamping) {
  // With every damping coefficient zero, d/dt E = nu^T tau = 0: C does no work and g is a
  // gradient. RK4 at 10 ms keeps E to well under 1e-6 relative over 5 s.
  RemusParams p;
  p.X_uu = p.Y_vv = p.Z_ww = p.M_qq = p.N_rr = 0.0;
  p.Z_uw = p.Z_uq = p.M_uw = p.M_uq = p.Y_uv = p.Y_ur = p.N_uv = p.N_ur = 0.0;
  const FossenModel model(p);
  Rng rng(99);
  for (int trial = 0; trial < 50; ++trial) {
    PlantState x;
    x.eta = RandomEta(&rng, 0.5);
    x.nu = RandomNu(&rng, 2.5, 0.5);
    const double e0 = model.Energy(x.eta, x.nu);
    for (int k = 0; k < 250; ++k) Integrate(model, Vec5::Zero(), Vec3::Zero(), 0.02, 2, &x);
    EXPECT_NEAR(model.Energy(x.eta, x.nu), e0, 1e-6 * e0) << "trial " << trial;
  }
}

// ---------------------------------------------------------------------------------------
// Kinematics

TEST(FossenKinematicsTest, JInverseTimesJIsIdentity) {
  Rng rng(5);
  const double max_theta = 80.0 * kPiD / 180.0;
  for (int k = 0; k < 2000; ++k) {
    const Vec5 eta = RandomEta(&rng, max_theta);
    const AttitudeTrig<double> trig(eta);
    const Mat5 J = FossenModel::J(eta);
    const Mat5 Ji = FossenModel::JInv(eta);
    ASSERT_LE((Ji * J - Mat5::Identity()).cwiseAbs().maxCoeff(), 1e-12) << eta.transpose();
    ASSERT_LE((J * Ji - Mat5::Identity()).cwiseAbs().maxCoeff(), 1e-12) << eta.transpose();
    const Mat5 Jt = FossenModel::J(trig);
    const Mat5 Jit = FossenModel::JInv(trig);
    ASSERT_LE((Jit * Jt - Mat5::Identity()).cwiseAbs().maxCoeff(), 1e-12) << eta.transpose();
    // Both overloads build the same matrices.
    ASSERT_EQ(Jt, J);
    ASSERT_EQ(Jit, Ji);
  }
}

TEST(FossenKinematicsTest, JIsRotationPlusEulerRates) {
  // The translational block is a rotation (R^T R = I, det R = +1) and theta_dot = q,
  // psi_dot = r / cos(theta).
  Rng rng(6);
  for (int k = 0; k < 500; ++k) {
    const Vec5 eta = RandomEta(&rng, 1.2);
    const Mat5 J = FossenModel::J(eta);
    const Mat3 R = J.topLeftCorner<3, 3>();
    ASSERT_LE((R.transpose() * R - Mat3::Identity()).norm(), 1e-14);
    ASSERT_NEAR(R.determinant(), 1.0, 1e-14);
    ASSERT_EQ((J.topRightCorner<3, 2>().norm()), 0.0);
    ASSERT_EQ((J.bottomLeftCorner<2, 3>().norm()), 0.0);
    ASSERT_EQ(J(3, 3), 1.0);
    ASSERT_EQ(J(3, 4), 0.0);
    ASSERT_EQ(J(4, 3), 0.0);
    ASSERT_NEAR(J(4, 4), 1.0 / std::cos(eta(3)), 1e-14 / std::cos(eta(3)));
  }
  // Surge at zero attitude moves north; at psi = 90 deg east; positive pitch dives
  // upward (NED: z_dot = -sin(theta) u).
  Vec5 nu = Vec5::Zero();
  nu(0) = 1.0;
  Vec5 eta = Vec5::Zero();
  EXPECT_LE((FossenModel::EtaDot(eta, nu) - (Vec5() << 1, 0, 0, 0, 0).finished()).norm(), 1e-15);
  eta(4) = kPiD / 2;
  EXPECT_LE((FossenModel::EtaDot(eta, nu) - (Vec5() << 0, 1, 0, 0, 0).finished()).norm(), 1e-15);
  eta(4) = 0.0;
  eta(3) = 0.3;
  EXPECT_NEAR(FossenModel::EtaDot(eta, nu)(2), -std::sin(0.3), 1e-15);
}

TEST(FossenKinematicsTest, EtaDotEqualsJTimesNu) {
  Rng rng(7);
  for (int k = 0; k < 2000; ++k) {
    const Vec5 eta = RandomEta(&rng, 1.3);
    const Vec5 nu = RandomNu(&rng, 3.0, 1.0);
    const Vec5 expected = FossenModel::J(eta) * nu;
    const Vec5 got = FossenModel::EtaDot(eta, nu);
    const Vec5 got_trig = FossenModel::EtaDot(AttitudeTrig<double>(eta), nu);
    ASSERT_LE((got - expected).cwiseAbs().maxCoeff(), 1e-14 * (1.0 + expected.norm()));
    ASSERT_EQ(got_trig, got);
  }
}

TEST(FossenKinematicsTest, JDotNuMatchesFiniteDifference) {
  // d/dt [J(eta(t)) nu] at fixed nu along eta_dot = J(eta) nu, by central differences.
  Rng rng(8);
  const double h = 1e-5;
  for (int k = 0; k < 2000; ++k) {
    const Vec5 eta = RandomEta(&rng, 1.2);
    const Vec5 nu = RandomNu(&rng, 2.5, 1.0);
    const Vec5 eta_dot = FossenModel::J(eta) * nu;
    const Vec5 fd = (FossenModel::J(Vec5(eta + h * eta_dot)) * nu -
                     FossenModel::J(Vec5(eta - h * eta_dot)) * nu) /
                    (2.0 * h);
    const Vec5 got = FossenModel::JDotNu(eta, nu);
    ASSERT_LE((got - fd).cwiseAbs().maxCoeff(), 1e-6 * (1.0 + fd.norm()))
        << "k=" << k << "\neta=" << eta.transpose() << "\nnu=" << nu.transpose()
        << "\nJdot nu=" << got.transpose() << "\nfd=" << fd.transpose();
    ASSERT_EQ(FossenModel::JDotNu(AttitudeTrig<double>(eta), nu), got);
  }
}

// ---------------------------------------------------------------------------------------
// ShiftAngle / ShiftTrig

TEST(FossenShiftTrigTest, SmallIncrementsMatchStdSinCos) {
  Rng rng(9);
  std::vector<double> increments = {0.0, 0.05, -0.05, 1e-9, -1e-9, 0.049999, 0.025};
  for (int k = 0; k < 5000; ++k) increments.push_back(U(&rng, -0.05, 0.05));
  Rng rng_a(10);
  for (double d : increments) {
    const double a = U(&rng_a, -kPiD, kPiD);
    double s = 0, c = 0;
    ShiftAngle(a, std::sin(a), std::cos(a), d, &s, &c);
    ASSERT_NEAR(s, std::sin(a + d), 1e-15) << "a=" << a << " d=" << d;
    ASSERT_NEAR(c, std::cos(a + d), 1e-15) << "a=" << a << " d=" << d;
  }
}

TEST(FossenShiftTrigTest, LargeIncrementsFallBackToStd) {
  // Beyond |d| = 0.05 the series would be wrong (by 2.5e-8 at d = 1): the result must be
  // std::sin/cos of a + d, bit for bit.
  Rng rng(11);
  const std::vector<double> fixed = {0.0500001, -0.0500001, 0.06, 0.3, 1.0, -1.0, 3.0, -6.0, 20.0};
  std::vector<double> increments = fixed;
  for (int k = 0; k < 2000; ++k) {
    const double mag = U(&rng, 0.0500001, 4.0);
    increments.push_back(rng.Uniform() < 0.5 ? -mag : mag);
  }
  for (double d : increments) {
    const double a = U(&rng, -kPiD, kPiD);
    double s = 0, c = 0;
    ShiftAngle(a, std::sin(a), std::cos(a), d, &s, &c);
    ASSERT_EQ(s, std::sin(a + d)) << "a=" << a << " d=" << d;
    ASSERT_EQ(c, std::cos(a + d)) << "a=" << a << " d=" << d;
  }
}

TEST(FossenShiftTrigTest, ShiftTrigMatchesFreshTrig) {
  Rng rng(12);
  for (int k = 0; k < 5000; ++k) {
    const Vec5 base = RandomEta(&rng, 1.2);
    const bool large = k % 5 == 0;
    const double span = large ? 2.0 : 0.05;
    Vec5 next = base + Vec5::Constant(U(&rng, -1, 1));  // positions move too
    next(3) = base(3) + U(&rng, -span, span);
    next(4) = base(4) + U(&rng, -span, span);
    const AttitudeTrig<double> shifted = ShiftTrig(AttitudeTrig<double>(base), base, next);
    ASSERT_NEAR(shifted.st, std::sin(next(3)), 1e-15) << k;
    ASSERT_NEAR(shifted.ct, std::cos(next(3)), 1e-15) << k;
    ASSERT_NEAR(shifted.sp, std::sin(next(4)), 1e-15) << k;
    ASSERT_NEAR(shifted.cp, std::cos(next(4)), 1e-15) << k;
  }
}

// The trig a follower carries from tick to tick (Integrate's trig_out, fed back as the
// next tick's trig, refreshed every 50 ticks as Follower does) stays within rounding of
// the trig of the state, over 5,000 ticks of a turning, pitching vehicle.
TEST(FossenShiftTrigTest, CarriedTrigStaysTheStatesTrig) {
  const FossenModel model;
  Rng rng(21);
  PlantState x;
  x.eta << 0, 0, 5, 0.2, 3.0;
  x.nu << 1.5, 0, 0, 0, 0;
  AttitudeTrig<double> carried(x.eta);
  double worst = 0;
  for (int k = 0; k < 5000; ++k) {
    if (k % 50 == 0) carried = AttitudeTrig<double>(x.eta);
    Vec5 tau;
    tau << 20, U(&rng, -5, 5), U(&rng, -5, 5), 2.0 * std::sin(0.01 * k), 3.0;
    const AttitudeTrig<double> now = carried;
    Integrate(model, tau, Vec3::Zero(), 0.02, 1, &x, &now, &carried);
    x.eta(4) = WrapAngle(x.eta(4));
    const AttitudeTrig<double> fresh(x.eta);
    worst = std::max({worst, std::abs(carried.st - fresh.st), std::abs(carried.ct - fresh.ct),
                      std::abs(carried.sp - fresh.sp), std::abs(carried.cp - fresh.cp)});
  }
  EXPECT_LT(worst, 1e-14);
  EXPECT_GT(std::abs(x.eta(4) - 3.0), 0.5);  // it did turn (and wrapped)
}

// ---------------------------------------------------------------------------------------
// RK4

TEST(FossenRk4Test, FourthOrderConvergence) {
  // A state whose velocities stay away from zero during the step (the quadratic damping
  // |v| v is not smooth at 0), with strong pitch and yaw rates so that the error of one
  // 20 ms step is well above round-off.
  const FossenModel model;
  PlantState x0;
  x0.eta << 0.0, 0.0, 0.0, 0.4, 1.0;
  x0.nu << 2.2, 0.8, -1.2, 1.5, -1.8;
  Vec5 tau;
  tau << 40.0, -8.0, 9.0, 5.0, -5.0;
  const Vec3 current(0.3, -0.2, 0.05);
  const double period = 0.02;

  PlantState ref = x0;
  Integrate(model, tau, current, period, 256, &ref);
  // The reference itself is converged far below the errors measured.
  PlantState ref2 = x0;
  Integrate(model, tau, current, period, 128, &ref2);
  ASSERT_LT(StateDistance(ref, ref2), 1e-12);

  std::vector<double> err;
  for (int substeps : {1, 2, 4, 8}) {
    PlantState x = x0;
    Integrate(model, tau, current, period, substeps, &x);
    err.push_back(StateDistance(x, ref));
  }
  // Errors well above round-off (about 1e-16 for these magnitudes).
  ASSERT_GT(err[2], 1e-12) << "error too small to measure the order";
  for (std::size_t k = 0; k + 1 < err.size(); ++k) {
    const double ratio = err[k] / err[k + 1];
    SCOPED_TRACE(::testing::Message() << "substeps " << (1 << k) << " -> " << (2 << k)
                                      << ": err " << err[k] << " -> " << err[k + 1]);
    if (err[k + 1] > 1e-13) {
      EXPECT_GT(ratio, 10.0);
      EXPECT_LT(ratio, 24.0);  // fourth, not higher, order: the test measures RK4
    }
  }
  // The first two halvings must always have been checked.
  EXPECT_GT(err[2], 1e-13);
}

TEST(FossenRk4Test, IntegrateSplitsThePeriodIntoEqualSteps) {
  const FossenModel model;
  PlantState a;
  a.eta << 1.0, 2.0, 3.0, 0.1, 0.2;
  a.nu << 1.5, 0.1, -0.1, 0.05, 0.1;
  PlantState b = a;
  const Vec5 tau = (Vec5() << 20, 1, -1, 0.5, 0.2).finished();
  Integrate(model, tau, Vec3::Zero(), 0.04, 4, &a);
  for (int k = 0; k < 4; ++k) {
    Rk4Step(model, tau, Vec3::Zero(), 0.01, AttitudeTrig<double>(b.eta), &b);
  }
  EXPECT_EQ(a.eta, b.eta);
  EXPECT_EQ(a.nu, b.nu);
  // Passing the initial state's trig (as the follower does) changes nothing.
  PlantState c = b;
  PlantState d = b;
  const AttitudeTrig<double> trig(c.eta);
  Integrate(model, tau, Vec3(0.2, 0.1, 0.0), 0.02, 2, &c, &trig);
  Integrate(model, tau, Vec3(0.2, 0.1, 0.0), 0.02, 2, &d);
  EXPECT_EQ(c.eta, d.eta);
  EXPECT_EQ(c.nu, d.nu);
}

/// The model's RK4 in still water written with its templated functions (Eigen vectors,
/// NuDot with a zero current): what the lane code of Rk4Step and IntegrateMany must equal.
void ReferenceRk4(const FossenModel& model, const Vec5& tau, double dt,
                  const AttitudeTrig<double>& trig, PlantState* x, AttitudeTrig<double>* out) {
  const Vec5 zero = Vec5::Zero();
  const Vec5 eta = x->eta, nu = x->nu;
  auto f = [&](const AttitudeTrig<double>& c, const Vec5& n, Vec5* ed, Vec5* nd) {
    *ed = FossenModel::EtaDot(c, n);
    *nd = model.NuDot(c, n, tau, zero);
  };
  Vec5 e1, n1, e2, n2, e3, n3, e4, n4;
  f(trig, nu, &e1, &n1);
  const Vec5 eta2 = eta + 0.5 * dt * e1;
  f(ShiftTrig(trig, eta, eta2), nu + 0.5 * dt * n1, &e2, &n2);
  const Vec5 eta3 = eta + 0.5 * dt * e2;
  f(ShiftTrig(trig, eta, eta3), nu + 0.5 * dt * n2, &e3, &n3);
  const Vec5 eta4 = eta + dt * e3;
  f(ShiftTrig(trig, eta, eta4), nu + dt * n3, &e4, &n4);
  x->eta = eta + dt / 6.0 * (e1 + 2.0 * e2 + 2.0 * e3 + e4);
  x->nu = nu + dt / 6.0 * (n1 + 2.0 * n2 + 2.0 * n3 + n4);
  *out = ShiftTrig(trig, eta, x->eta);
}

bool SameBits(const PlantState& a, const PlantState& b) {
  return std::memcmp(a.eta.data(), b.eta.data(), sizeof(double) * 5) == 0 &&
         std::memcmp(a.nu.data(), b.nu.data(), sizeof(double) * 5) == 0;
}
bool SameBits(const AttitudeTrig<double>& a, const AttitudeTrig<double>& b) {
  return std::memcmp(&a, &b, sizeof(a)) == 0;
}

/// A state whose RK4 stages turn by more than ShiftAngle's 0.05 rad in some steps (the
/// std::sin/cos fallback) when `fast` is set, and by less otherwise.
PlantState RandomPlant(Rng* rng, bool fast) {
  PlantState x;
  x.eta = RandomEta(rng, 1.2);
  x.nu = RandomNu(rng, 3.0, fast ? 6.0 : 0.5);
  return x;
}

Vec5 RandomTau(Rng* rng) {
  Vec5 tau;
  for (int k = 0; k < 5; ++k) tau(k) = U(rng, -200, 200);
  return tau;
}

TEST(FossenRk4Test, StillWaterStepIsTheModelsRk4ToTheBit) {
  const FossenModel model;
  Rng rng(77);
  for (int k = 0; k < 3000; ++k) {
    PlantState a = RandomPlant(&rng, k % 3 == 0);
    PlantState b = a;
    const Vec5 tau = RandomTau(&rng);
    const double dt = U(&rng, 0.001, 0.2);
    const AttitudeTrig<double> trig(a.eta);
    AttitudeTrig<double> out_a = trig, out_b = trig;
    Rk4Step(model, tau, Vec3::Zero(), dt, trig, &a, &out_a);
    ReferenceRk4(model, tau, dt, trig, &b, &out_b);
    ASSERT_TRUE(SameBits(a, b)) << k;
    ASSERT_TRUE(SameBits(out_a, out_b)) << k;
  }
}

// IntegrateMany steps still-water vehicles four to a vector: each one must end exactly as
// Integrate() leaves it alone, with every lane code, any count (full and short packs, a
// single vehicle), several substeps, with and without a given trig and a trig to return,
// vehicles in a current among them, and lanes that take the std::sin/cos fallback next to
// lanes that do not.
TEST(FossenRk4Test, IntegrateManyEqualsIntegrateForEveryVehicleToTheBit) {
  const FossenModel model;
  Rng rng(4242);
  for (const LaneCode code :
       {LaneCode::kBest, LaneCode::kAvx512, LaneCode::kAvx2, LaneCode::kBase}) {
    if (!CpuRuns(code)) continue;
    for (int round = 0; round < 300; ++round) {
      const int count = 1 + round % 11;
      const int substeps = 1 + round % 3;
      const double period = U(&rng, 0.005, 0.1);
      std::vector<PlantState> many(count), alone(count);
      std::vector<AttitudeTrig<double>> trig_many(count, AttitudeTrig<double>(Vec5::Zero()));
      std::vector<AttitudeTrig<double>> trig_alone = trig_many, given = trig_many;
      std::vector<PlantJob> jobs(count);
      for (int i = 0; i < count; ++i) {
        many[i] = alone[i] = RandomPlant(&rng, rng.Uniform() < 0.3);
        given[i] = AttitudeTrig<double>(many[i].eta);
        jobs[i].x = &many[i];
        jobs[i].tau = RandomTau(&rng);
        if (rng.Uniform() < 0.15) jobs[i].current_ned = Vec3(U(&rng, -1, 1), U(&rng, -1, 1), 0);
        if (rng.Uniform() < 0.7) jobs[i].trig = &given[i];
        if (rng.Uniform() < 0.7) jobs[i].trig_out = &trig_many[i];
      }
      IntegrateMany(model, period, substeps, jobs.data(), count, code);
      for (int i = 0; i < count; ++i) {
        const PlantJob& j = jobs[i];
        Integrate(model, j.tau, j.current_ned, period, substeps, &alone[i], j.trig,
                  j.trig_out ? &trig_alone[i] : nullptr);
        ASSERT_TRUE(SameBits(many[i], alone[i])) << "round " << round << " vehicle " << i;
        ASSERT_TRUE(SameBits(trig_many[i], trig_alone[i])) << "round " << round << " " << i;
      }
    }
  }
}

}  // namespace
}  // namespace shoal

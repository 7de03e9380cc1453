// Property tests of core/control.h: angle wrapping, feedback linearisation (eta'' = a),
// its saturated form (attitude keeps its authority), protocol (10) against a hand
// computation, and per-channel saturation.
#include "core/control.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "core/rng.h"

namespace shoal {
namespace {

double U(Rng* rng, double lo, double hi) { return lo + (hi - lo) * rng->Uniform(); }

Vec5 RandomEta(Rng* rng, double max_theta) {
  Vec5 eta;
  eta << U(rng, -100, 100), U(rng, -100, 100), U(rng, -50, 50), U(rng, -max_theta, max_theta),
      U(rng, -kPi, kPi);
  return eta;
}

Vec5 RandomNu(Rng* rng) {
  Vec5 nu;
  nu << U(rng, -0.5, 2.5), U(rng, -1, 1), U(rng, -1, 1), U(rng, -1, 1), U(rng, -1, 1);
  return nu;
}

Vec5 RandomVec(Rng* rng, double mag) {
  Vec5 v;
  for (int i = 0; i < 5; ++i) v(i) = U(rng, -mag, mag);
  return v;
}

/// eta'' = J(eta) nu_dot + J_dot(eta, nu) nu for the plant driven by tau (no current).
Vec5 EtaDDot(const FossenModel& model, const Vec5& eta, const Vec5& nu, const Vec5& tau) {
  const Vec5 nu_dot = model.NuDot(eta, nu, tau, Vec5(Vec5::Zero()));
  return FossenModel::J(eta) * nu_dot + FossenModel::JDotNu(eta, nu);
}

// ---------------------------------------------------------------------------------------
// WrapAngle / EtaDiff

TEST(ControlWrapAngleTest, BoundaryValues) {
  EXPECT_EQ(WrapAngle(0.0), 0.0);
  EXPECT_EQ(WrapAngle(kPi), kPi);        // pi stays pi
  EXPECT_EQ(WrapAngle(-kPi), kPi);       // -pi is outside (-pi, pi]
  EXPECT_EQ(WrapAngle(3.0 * kPi), kPi);
  EXPECT_EQ(WrapAngle(-3.0 * kPi), kPi);
  EXPECT_EQ(WrapAngle(5.0 * kPi), kPi);
  EXPECT_NEAR(WrapAngle(2.0 * kPi), 0.0, 1e-15);
  EXPECT_NEAR(WrapAngle(-2.0 * kPi), 0.0, 1e-15);
  EXPECT_NEAR(WrapAngle(7.0), 7.0 - 2.0 * kPi, 1e-15);
  EXPECT_NEAR(WrapAngle(-7.0), -7.0 + 2.0 * kPi, 1e-15);
  EXPECT_NEAR(WrapAngle(3.1 + 2.0 * kPi), 3.1, 1e-14);
  EXPECT_NEAR(WrapAngle(-3.1 - 4.0 * kPi), -3.1, 1e-14);
  // Just inside the interval is returned untouched.
  const double below_pi = std::nextafter(kPi, 0.0);
  const double above_minus_pi = std::nextafter(-kPi, 0.0);
  EXPECT_EQ(WrapAngle(below_pi), below_pi);
  EXPECT_EQ(WrapAngle(above_minus_pi), above_minus_pi);
}

TEST(ControlWrapAngleTest, RandomValuesLandInHalfOpenIntervalOnTheSameCircle) {
  Rng rng(1);
  for (int k = 0; k < 100000; ++k) {
    const double mag = k < 50000 ? 20.0 : 1e6;
    const double a = U(&rng, -mag, mag);
    const double w = WrapAngle(a);
    ASSERT_GT(w, -kPi) << a;
    ASSERT_LE(w, kPi) << a;
    // Same angle: sin/cos agree (error grows with |a| through the rounding of a + pi).
    const double tol = 1e-13 + 1e-15 * std::abs(a);
    ASSERT_NEAR(std::sin(w), std::sin(a), tol) << a;
    ASSERT_NEAR(std::cos(w), std::cos(a), tol) << a;
    // Differs from a by a whole number of turns.
    const double turns = (a - w) / (2.0 * kPi);
    ASSERT_NEAR(turns, std::round(turns), 1e-9) << a;
    if (a > -kPi && a <= kPi) {
      ASSERT_EQ(w, a);
    }
  }
  // Very large values still land in the interval.
  for (double a : {1e12, -1e12, 1e15, -1e15, 123456789.0}) {
    const double w = WrapAngle(a);
    EXPECT_GT(w, -kPi) << a;
    EXPECT_LE(w, kPi) << a;
  }
}

TEST(ControlEtaDiffTest, WrapsOnlyTheAngles) {
  Vec5 a, b;
  a << 10.0, 0.0, -4.0, 3.0, 3.1;
  b << -10.0, 7.0, 4.0, -3.0, -3.1;
  const Vec5 d = EtaDiff(a, b);
  EXPECT_EQ(d(0), 20.0);  // positions are never wrapped, whatever their size
  EXPECT_EQ(d(1), -7.0);
  EXPECT_EQ(d(2), -8.0);
  EXPECT_NEAR(d(3), 6.0 - 2.0 * kPi, 1e-15);  // 0.2832 rad the short way round
  EXPECT_NEAR(d(4), 6.2 - 2.0 * kPi, 1e-15);  // -0.0832
  // Antisymmetric in its arguments on the angles too.
  const Vec5 r = EtaDiff(b, a);
  EXPECT_NEAR(r(3), -d(3), 1e-15);
  EXPECT_NEAR(r(4), -d(4), 1e-15);
  EXPECT_EQ(r.head<3>(), -d.head<3>());
}

// ---------------------------------------------------------------------------------------
// Feedback linearisation

TEST(ControlFeedbackLinearisationTest, YieldsCommandedEtaDDot) {
  const FossenModel model;
  Rng rng(2024);
  for (int k = 0; k < 2000; ++k) {
    // Given a random state (|theta| < 1.2 rad) and a random O(1) acceleration demand.
    const Vec5 eta = RandomEta(&rng, 1.2);
    const Vec5 nu = RandomNu(&rng);
    const Vec5 a = RandomVec(&rng, 1.0);
    // When tau = FL(a) drives the plant.
    const Vec5 tau = FeedbackLinearise(model, eta, nu, a);
    // Then eta'' = a.
    const Vec5 eta_ddot = EtaDDot(model, eta, nu, tau);
    ASSERT_LE((eta_ddot - a).cwiseAbs().maxCoeff(), 1e-9)
        << "k=" << k << "\neta=" << eta.transpose() << "\nnu=" << nu.transpose()
        << "\na=" << a.transpose() << "\neta''=" << eta_ddot.transpose();
  }
}

TEST(ControlFeedbackLinearisationTest, EtaDotToWritesWhatEtaDotReturns) {
  Rng rng(12);
  for (int k = 0; k < 200; ++k) {
    Vec5 eta, nu;
    for (int i = 0; i < 5; ++i) {
      eta(i) = -3.0 + 6.0 * rng.Uniform();
      nu(i) = -2.0 + 4.0 * rng.Uniform();
    }
    eta(3) = -1.2 + 2.4 * rng.Uniform();  // pitch within the model's range
    const AttitudeTrig<double> trig(eta);
    Vec5 into = Vec5::Constant(std::nan(""));
    FossenModel::EtaDotTo(trig, nu, &into);
    const Vec5 returned = FossenModel::EtaDot(trig, nu);
    EXPECT_EQ(std::memcmp(into.data(), returned.data(), sizeof(double) * 5), 0) << k;
    // And both are J(eta) nu.
    EXPECT_LT((returned - FossenModel::J(eta) * nu).cwiseAbs().maxCoeff(), 1e-12) << k;
  }
}

TEST(ControlFeedbackLinearisationTest, EtaDDotAgreesWithFiniteDifferenceOfEtaDot) {
  // Independent of JDotNu: differentiate eta_dot = J(eta) nu numerically along the
  // trajectory (eta_dot, nu_dot) produced by tau.
  const FossenModel model;
  Rng rng(31);
  const double h = 1e-5;
  for (int k = 0; k < 1000; ++k) {
    const Vec5 eta = RandomEta(&rng, 1.2);
    const Vec5 nu = RandomNu(&rng);
    const Vec5 a = RandomVec(&rng, 1.0);
    const Vec5 tau = FeedbackLinearise(model, eta, nu, a);
    const Vec5 nu_dot = model.NuDot(eta, nu, tau, Vec5(Vec5::Zero()));
    const Vec5 eta_dot = FossenModel::EtaDot(eta, nu);
    const Vec5 fd = (FossenModel::EtaDot(Vec5(eta + h * eta_dot), Vec5(nu + h * nu_dot)) -
                     FossenModel::EtaDot(Vec5(eta - h * eta_dot), Vec5(nu - h * nu_dot))) /
                    (2.0 * h);
    ASSERT_LE((fd - a).cwiseAbs().maxCoeff(), 1e-6) << "k=" << k;
  }
}

TEST(ControlFeedbackLinearisationTest, SaturatedWithHugeLimitsEqualsUnsaturated) {
  const FossenModel model;
  const Vec5 huge = Vec5::Constant(1e12);
  Rng rng(2025);
  for (int k = 0; k < 2000; ++k) {
    const Vec5 eta = RandomEta(&rng, 1.2);
    const Vec5 nu = RandomNu(&rng);
    const Vec5 a = RandomVec(&rng, 1.0);
    const Vec5 expected = FeedbackLinearise(model, eta, nu, a);
    Vec5 tau = Vec5::Constant(std::numeric_limits<double>::quiet_NaN());
    Vec5 wanted = Vec5::Zero();
    const bool saturated = SaturatedFeedbackLinearise(model, eta, nu, a, huge, &tau, &wanted);
    ASSERT_FALSE(saturated) << "k=" << k;
    const double tol = 1e-12 * (1.0 + expected.cwiseAbs().maxCoeff());
    ASSERT_LE((tau - expected).cwiseAbs().maxCoeff(), tol) << "k=" << k;
    ASSERT_LE((wanted - expected).cwiseAbs().maxCoeff(), tol) << "k=" << k;
    // The AttitudeTrig overload is the same computation.
    Vec5 tau_trig;
    SaturatedFeedbackLinearise(model, AttitudeTrig<double>(eta), nu, a, huge, &tau_trig);
    ASSERT_EQ(tau_trig, tau);
    // And the plant does what was asked.
    ASSERT_LE((EtaDDot(model, eta, nu, tau) - a).cwiseAbs().maxCoeff(), 1e-9) << "k=" << k;
  }
}

TEST(ControlFeedbackLinearisationTest, SaturationFlagAtTheLimitOfEachChannel) {
  // A limit a hair below the demand clips (and is reported); a hair above does not.
  const FossenModel model;
  Rng rng(12);
  for (int k = 0; k < 200; ++k) {
    const Vec5 eta = RandomEta(&rng, 0.5);
    const Vec5 nu = RandomNu(&rng);
    const Vec5 a = RandomVec(&rng, 1.0);
    Vec5 wanted, tau;
    SaturatedFeedbackLinearise(model, eta, nu, a, Vec5::Constant(1e12), &tau, &wanted);
    for (int i = 0; i < 5; ++i) {
      if (std::abs(wanted(i)) < 1e-3) continue;
      Vec5 lim = Vec5::Constant(1e12);
      lim(i) = std::abs(wanted(i)) * (1.0 - 1e-7);
      ASSERT_TRUE(SaturatedFeedbackLinearise(model, eta, nu, a, lim, &tau)) << k << " " << i;
      ASSERT_EQ(std::abs(tau(i)), lim(i)) << k << " " << i;
      lim(i) = std::abs(wanted(i)) * (1.0 + 1e-7);
      ASSERT_FALSE(SaturatedFeedbackLinearise(model, eta, nu, a, lim, &tau)) << k << " " << i;
    }
  }
}

// SaturatedFeedbackLineariseMany runs the inner loops of many followers four to a vector:
// every one must get the bits the scalar function gives it, saturated or not, with every
// lane code and any count (full and short packs, one alone).
TEST(ControlFeedbackLinearisationTest, ManyAtOnceEqualsOneByOneToTheBit) {
  const FossenModel model;
  Rng rng(31);
  for (const LaneCode code :
       {LaneCode::kBest, LaneCode::kAvx512, LaneCode::kAvx2, LaneCode::kBase}) {
    if (!CpuRuns(code)) continue;
    int saturated = 0, free = 0;
    for (int round = 0; round < 400; ++round) {
      const int count = 1 + round % 9;
      std::vector<ForceJob> jobs(count);
      std::vector<ForceJob*> ptrs;
      for (ForceJob& j : jobs) {
        j.trig = AttitudeTrig<double>(RandomEta(&rng, 1.2));
        j.nu = RandomNu(&rng);
        j.a = RandomVec(&rng, 2.0);
        // Limits that clip some channels of some vehicles, and none of others.
        for (int k = 0; k < 5; ++k) j.tau_max(k) = rng.Uniform() < 0.3 ? U(&rng, 1, 60) : 1e4;
        ptrs.push_back(&j);
      }
      SaturatedFeedbackLineariseMany(model, ptrs.data(), count, code);
      for (const ForceJob& j : jobs) {
        Vec5 tau, wanted;
        const bool sat =
            SaturatedFeedbackLinearise(model, j.trig, j.nu, j.a, j.tau_max, &tau, &wanted);
        ASSERT_EQ(sat, j.saturated) << round;
        ASSERT_EQ(std::memcmp(tau.data(), j.tau.data(), sizeof(double) * 5), 0) << round;
        ASSERT_EQ(std::memcmp(wanted.data(), j.wanted.data(), sizeof(double) * 5), 0) << round;
        (sat ? saturated : free) += 1;
      }
    }
    // Both kinds of vehicle were checked.
    EXPECT_GT(saturated, 100);
    EXPECT_GT(free, 100);
  }
}

TEST(ControlFeedbackLinearisationTest, ClippedHeaveKeepsPitchAuthority) {
  const FossenModel model;
  const Vec5 tau_max = (Vec5() << 100.0, 10.0, 10.0, 6.0, 6.0).finished();
  // Given a dive demand that needs far more than 10 N of heave force but a modest pitch
  // acceleration.
  Vec5 eta, nu, a;
  eta << 5.0, -3.0, 10.0, 0.1, 0.3;
  nu << 1.5, 0.02, 0.02, 0.05, 0.02;
  a << 0.0, 0.0, 1.0, 0.1, 0.0;
  const Vec5 nd = FossenModel::JInv(eta) * (a - FossenModel::JDotNu(eta, nu));
  Vec5 tau, wanted;
  // When the saturated feedback linearisation computes tau.
  const bool saturated = SaturatedFeedbackLinearise(model, eta, nu, a, tau_max, &tau, &wanted);
  // Then Z is clipped, M is not, and the pitch (and yaw) accelerations are as commanded.
  ASSERT_GT(std::abs(wanted(2)), 10.0);
  EXPECT_TRUE(saturated);
  EXPECT_EQ(std::abs(tau(2)), 10.0);
  ASSERT_LT(std::abs(tau(3)), 6.0);
  ASSERT_LT(std::abs(tau(4)), 6.0);
  const Vec5 nu_dot = model.NuDot(eta, nu, tau, Vec5(Vec5::Zero()));
  EXPECT_NEAR(nu_dot(3), nd(3), 1e-9);
  EXPECT_NEAR(nu_dot(4), nd(4), 1e-9);
  // Whereas clipping the plain FL demand channel by channel loses the pitch command
  // (this is what the saturated form exists to avoid, and shows the check above bites).
  Vec5 naive = FeedbackLinearise(model, eta, nu, a);
  Saturate(tau_max, &naive);
  ASSERT_LT(std::abs(naive(3)), 6.0);
  const Vec5 naive_nu_dot = model.NuDot(eta, nu, naive, Vec5(Vec5::Zero()));
  EXPECT_GT(std::abs(naive_nu_dot(3) - nd(3)), 1e-3);
}

TEST(ControlFeedbackLinearisationTest, ClippedForcesKeepAttitudeAuthorityAtRandomStates) {
  const FossenModel model;
  const Vec5 tau_max = (Vec5() << 100.0, 10.0, 10.0, 6.0, 6.0).finished();
  Rng rng(555);
  int pitch_cases = 0, yaw_cases = 0;  // attitude moment unclipped, its force clipped
  for (int k = 0; k < 20000; ++k) {
    const Vec5 eta = RandomEta(&rng, 0.5);
    const Vec5 nu = RandomNu(&rng);
    Vec5 a = RandomVec(&rng, 1.0);
    a(3) *= 0.3;
    a(4) *= 0.3;
    Vec5 tau, wanted;
    const bool saturated = SaturatedFeedbackLinearise(model, eta, nu, a, tau_max, &tau, &wanted);
    // Every channel within its limit; flagged iff something was clipped.
    for (int i = 0; i < 5; ++i) ASSERT_LE(std::abs(tau(i)), tau_max(i));
    const bool any_over = ((wanted.cwiseAbs() - tau_max).array() > 0.0).any();
    if (any_over) {
      ASSERT_TRUE(saturated) << "k=" << k;
    }
    const Vec5 nd = FossenModel::JInv(eta) * (a - FossenModel::JDotNu(eta, nu));
    const Vec5 nu_dot = model.NuDot(eta, nu, tau, Vec5(Vec5::Zero()));
    if (std::abs(tau(3)) < tau_max(3)) {
      if (std::abs(wanted(2)) > tau_max(2)) ++pitch_cases;
      ASSERT_NEAR(nu_dot(3), nd(3), 1e-9) << "k=" << k << " tau=" << tau.transpose();
    }
    if (std::abs(tau(4)) < tau_max(4)) {
      if (std::abs(wanted(1)) > tau_max(1)) ++yaw_cases;
      ASSERT_NEAR(nu_dot(4), nd(4), 1e-9) << "k=" << k << " tau=" << tau.transpose();
    }
    // The force channels that were not clipped also get their commanded surge.
    if (std::abs(tau(0)) < tau_max(0)) {
      ASSERT_NEAR(nu_dot(0), nd(0), 1e-9) << "k=" << k;
    }
  }
  // The property was exercised, in states where heave/sway really were clipped.
  EXPECT_GT(pitch_cases, 500);
  EXPECT_GT(yaw_cases, 500);
}

// ---------------------------------------------------------------------------------------
// Protocol (10)

TEST(ControlProtocol10Test, MatchesHandComputation) {
  const double k1 = 0.5, k2 = 2.0;
  Vec5 offset_i;
  offset_i << 1.0, -2.0, 0.5, 0.0, 0.0;
  NeighbourTerm t[3];
  // Term 1: the leader (no offset), own state at its send time t - tau_i0. Headings on
  // either side of +-pi: 3.1 - (-3.1) = 6.2 wraps to 6.2 - 2 pi = -0.0831853071795862.
  t[0].weight = 1.0;
  t[0].eta_j << 10.0, 5.0, -3.0, 0.1, 3.1;
  t[0].eta_dot_j << 1.0, 0.5, -0.1, 0.0, 0.02;
  t[0].offset_j = Vec5::Zero();
  t[0].eta_i << 8.0, 6.0, -2.0, 0.05, -3.1;
  t[0].eta_dot_i << 0.8, 0.4, 0.0, 0.01, -0.01;
  // Term 2: follower j with weight 2, own state at a different (older) send time.
  // Heading -3.0 - 2.9 = -5.9 wraps to 2 pi - 5.9 = 0.3831853071795862.
  t[1].weight = 2.0;
  t[1].eta_j << 4.0, 9.0, -1.0, -0.2, -3.0;
  t[1].eta_dot_j << 1.2, 0.0, 0.1, 0.02, -0.05;
  t[1].offset_j << -1.0, 3.0, 0.0, 0.0, 0.0;
  t[1].eta_i << 7.0, 5.0, -1.5, 0.1, 2.9;
  t[1].eta_dot_i << 1.0, 0.1, 0.0, 0.0, 0.0;
  // Term 3: weight 0.5, no wrapping.
  t[2].weight = 0.5;
  t[2].eta_j << 3.0, 2.0, 0.0, 0.0, 1.0;
  t[2].eta_dot_j << 0.5, 0.5, 0.0, 0.0, 0.1;
  t[2].offset_j << 2.0, 0.0, -1.0, 0.0, 0.0;
  t[2].eta_i << 1.0, 1.0, 1.0, 0.0, 0.5;
  t[2].eta_dot_i << 0.5, 0.0, 0.0, 0.0, 0.0;

  // By hand, term k = w [k1 ((eta_j - d_j) - (eta_i - d_i)) + k2 (eta_dot_j - eta_dot_i)]:
  //  1: e = [3, -3, -0.5, 0.05, -0.0831853]; de = [0.2, 0.1, -0.1, -0.01, 0.03]
  //     -> [1.9, -1.3, -0.45, 0.005, 0.0184073464102069]        (psi: 3.16 - pi)
  //  2: e = [-1, -1, 1, -0.3, 0.3831853]; de = [0.2, -0.1, 0.1, 0.02, -0.05]
  //     -> 2 * [-0.1, -0.7, 0.7, -0.11, 0.0915926535897931]
  //      = [-0.2, -1.4, 1.4, -0.22, 0.1831853071795862]          (psi: 2 pi - 6.1)
  //  3: e = [1, -1, 0.5, 0, 0.5]; de = [0, 0.5, 0, 0, 0.1]
  //     -> 0.5 * [0.5, 0.5, 0.25, 0, 0.45] = [0.25, 0.25, 0.125, 0, 0.225]
  const Vec5 term1 = (Vec5() << 1.9, -1.3, -0.45, 0.005, 0.0184073464102069).finished();
  const Vec5 term2 = (Vec5() << -0.2, -1.4, 1.4, -0.22, 0.1831853071795862).finished();
  const Vec5 term3 = (Vec5() << 0.25, 0.25, 0.125, 0.0, 0.225).finished();
  //  sum: [1.95, -2.45, 1.075, -0.215, pi - 2.715 = 0.4265926535897931]
  const Vec5 sum = (Vec5() << 1.95, -2.45, 1.075, -0.215, 0.4265926535897931).finished();

  const double tol = 1e-13;
  EXPECT_LE((Protocol10(k1, k2, offset_i, &t[0], 1) - term1).cwiseAbs().maxCoeff(), tol)
      << Protocol10(k1, k2, offset_i, &t[0], 1).transpose();
  EXPECT_LE((Protocol10(k1, k2, offset_i, &t[1], 1) - term2).cwiseAbs().maxCoeff(), tol)
      << Protocol10(k1, k2, offset_i, &t[1], 1).transpose();
  EXPECT_LE((Protocol10(k1, k2, offset_i, &t[2], 1) - term3).cwiseAbs().maxCoeff(), tol)
      << Protocol10(k1, k2, offset_i, &t[2], 1).transpose();
  const Vec5 got = Protocol10(k1, k2, offset_i, t, 3);
  EXPECT_LE((got - sum).cwiseAbs().maxCoeff(), tol) << got.transpose();
  // No neighbours: no demand.
  EXPECT_EQ(Protocol10(k1, k2, offset_i, t, 0), Vec5::Zero());
}

TEST(ControlProtocol10Test, TermsHaveTheBitsOfTheVectorForm) {
  // AddProtocol10Term computes component by component (so that its stores can be
  // forwarded); it must give, to the bit, the vector form of protocol (10)'s term:
  //   e = (eta_j - d_j) - (eta_i - d_i), angles wrapped; a += w (k1 e + k2 (eta_dot_j - eta_dot_i))
  // here with headings and pitches on both sides of +-pi and several turns off.
  Rng rng(11);
  const auto u = [&](double lo, double hi) { return lo + (hi - lo) * rng.Uniform(); };
  const auto vec = [&](double scale, double angle) {
    return Vec5Of(u(-scale, scale), u(-scale, scale), u(-scale, scale), u(-angle, angle),
                  u(-angle, angle));
  };
  int wrapped = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const double k1 = u(0.0, 2.0), k2 = u(0.0, 3.0), w = u(0.0, 4.0);
    const Vec5 d_i = vec(20.0, 0.0), d_j = vec(20.0, 0.0);
    const Vec5 eta_j = vec(500.0, 12.0), eta_i = vec(500.0, 12.0);
    const Vec5 dot_j = vec(3.0, 1.0), dot_i = vec(3.0, 1.0);
    const Vec5 a0 = vec(5.0, 5.0);

    Vec5 e = (eta_j - d_j) - (eta_i - d_i);
    wrapped += std::abs(e(4)) > kPi;
    e(3) = WrapAngle(e(3));
    e(4) = WrapAngle(e(4));
    const Vec5 want = a0 + w * (k1 * e + k2 * (dot_j - dot_i));

    Vec5 got = a0;
    AddProtocol10Term(k1, k2, d_i, w, eta_j, dot_j, d_j, eta_i, dot_i, &got);
    ASSERT_EQ(std::memcmp(got.data(), want.data(), sizeof(double) * 5), 0)
        << "trial " << trial << ": " << got.transpose() << " against " << want.transpose();
  }
  EXPECT_GT(wrapped, 1000);  // the wrap was exercised
}

TEST(ControlProtocol10Test, Vec5OfKeepsTheOrderOfItsComponents) {
  const Vec5 v = Vec5Of(1.5, -2.25, 3.0, -0.125, 7.0);
  EXPECT_EQ(v, (Vec5() << 1.5, -2.25, 3.0, -0.125, 7.0).finished());
  // And EtaDiff, built by it, wraps only the two angles.
  const Vec5 a = Vec5Of(10.0, 20.0, 30.0, 3.0, -3.0), b = Vec5Of(1.0, 2.0, 3.0, -3.0, 3.0);
  const Vec5 d = EtaDiff(a, b);
  EXPECT_EQ(d(0), 9.0);
  EXPECT_EQ(d(1), 18.0);
  EXPECT_EQ(d(2), 27.0);
  EXPECT_EQ(d(3), WrapAngle(6.0));
  EXPECT_EQ(d(4), WrapAngle(-6.0));
}

TEST(ControlProtocol10Test, ConsensusAtTheOffsetsGivesZero) {
  // Every follower exactly at its slot, moving with the leader, headings equal modulo
  // 2 pi: a_i = 0.
  Vec5 offset_i;
  offset_i << -5.0, 2.0, 1.0, 0.0, 0.0;
  Vec5 leader, leader_dot;
  leader << 100.0, -20.0, 30.0, 0.2, 3.0;
  leader_dot << 1.0, 0.5, -0.1, 0.0, 0.05;
  NeighbourTerm t[2];
  t[0].weight = 1.0;
  t[0].eta_j = leader;
  t[0].eta_dot_j = leader_dot;
  t[0].eta_i = leader + offset_i;
  t[0].eta_i(4) -= 2.0 * kPi;
  t[0].eta_dot_i = leader_dot;
  t[1].weight = 3.0;
  t[1].offset_j << 4.0, 4.0, 0.0, 0.0, 0.0;
  t[1].eta_j = leader + t[1].offset_j;
  t[1].eta_dot_j = leader_dot;
  t[1].eta_i = leader + offset_i;
  t[1].eta_dot_i = leader_dot;
  EXPECT_LE(Protocol10(0.7, 1.3, offset_i, t, 2).cwiseAbs().maxCoeff(), 1e-12);
}

// ---------------------------------------------------------------------------------------
// Saturate

TEST(ControlSaturateTest, ClipsPerChannelAndReportsClipping) {
  const Vec5 tau_max = (Vec5() << 100.0, 10.0, 10.0, 6.0, 6.0).finished();
  Vec5 tau;
  tau << 150.0, -20.0, 5.0, 6.0, -7.0;
  EXPECT_TRUE(Saturate(tau_max, &tau));
  EXPECT_EQ(tau, (Vec5() << 100.0, -10.0, 5.0, 6.0, -6.0).finished());

  // Within (or exactly at) the limits: untouched and not reported.
  Vec5 inside;
  inside << -100.0, 9.99, 0.0, -6.0, 1.0;
  const Vec5 copy = inside;
  EXPECT_FALSE(Saturate(tau_max, &inside));
  EXPECT_EQ(inside, copy);

  // Each channel alone is clipped and reported.
  for (int i = 0; i < 5; ++i) {
    Vec5 one = Vec5::Zero();
    one(i) = -2.0 * tau_max(i);
    EXPECT_TRUE(Saturate(tau_max, &one)) << i;
    Vec5 expected = Vec5::Zero();
    expected(i) = -tau_max(i);
    EXPECT_EQ(one, expected) << i;
  }
  EXPECT_EQ(Clip(3.0, 2.0), 2.0);
  EXPECT_EQ(Clip(-3.0, 2.0), -2.0);
  EXPECT_EQ(Clip(1.5, 2.0), 1.5);
}

}  // namespace
}  // namespace shoal

// The follower's control law: protocol (10) (outer, desired eta'') and feedback
// linearisation of the Fossen model (inner, force/moment), with saturation.
#pragma once

#include <cmath>

#include "core/fossen.h"

namespace shoal {

constexpr double kPi = 3.14159265358979323846;

/// Wraps an angle to (-pi, pi].
inline double WrapAngle(double a) {
  if (a > -kPi && a <= kPi) return a;
  if (a > kPi && a <= 3.0 * kPi) return a - 2.0 * kPi;  // one turn off: no fmod
  if (a > -3.0 * kPi && a <= -kPi) return a + 2.0 * kPi;
  a = std::fmod(a + kPi, 2.0 * kPi);
  if (a <= 0.0) a += 2.0 * kPi;
  return a - kPi;
}

/// eta_a - eta_b with the angle components (theta, psi) wrapped to (-pi, pi].
inline Vec5 EtaDiff(const Vec5& a, const Vec5& b) {
  return Vec5Of(a(0) - b(0), a(1) - b(1), a(2) - b(2), WrapAngle(a(3) - b(3)),
                WrapAngle(a(4) - b(4)));
}

/// Formation offset d_i as a 5-vector (position only; attitude offsets are zero).
inline Vec5 OffsetVec(const Vec3& d) {
  Vec5 o = Vec5::Zero();
  o.head<3>() = d;
  return o;
}

/// One term of protocol (10): a neighbour's message and the receiver's own state at
/// that message's send time.
struct NeighbourTerm {
  double weight = 1.0;           // a_ij (or a_i0 for the leader)
  Vec5 eta_j = Vec5::Zero();     // neighbour's eta at send time (from its message)
  Vec5 eta_dot_j = Vec5::Zero();
  Vec5 offset_j = Vec5::Zero();  // d_j (zero for the leader)
  Vec5 eta_i = Vec5::Zero();     // own eta at the same send time (own history)
  Vec5 eta_dot_i = Vec5::Zero();
};

/// Adds one neighbour's term of protocol (10) to *a: the sum Protocol10 forms, term by
/// term, for a caller that reads the operands where they lie rather than copying them into
/// a NeighbourTerm.
inline void AddProtocol10Term(double k1, double k2, const Vec5& offset_i, double weight,
                              const Vec5& eta_j, const Vec5& eta_dot_j, const Vec5& offset_j,
                              const Vec5& eta_i, const Vec5& eta_dot_i, Vec5* a) {
  // e = EtaDiff(eta_j - offset_j, eta_i - offset_i); a += weight (k1 e + k2 (eta_dot_j -
  // eta_dot_i)), one component at a time with the same operations, the sum stored by
  // Vec5Of: as vectors, e's wrapped angles would be stored over halves of stored pairs and
  // the pairs read back whole, which the CPU cannot forward.
  // (Components as expressions, not a loop over an array: the array would be stored and
  // read back in pairs, the very load that stalls.)
  const auto e = [&](int k) { return (eta_j(k) - offset_j(k)) - (eta_i(k) - offset_i(k)); };
  const auto sum = [&](int k, double ek) {
    return (*a)(k) + weight * (k1 * ek + k2 * (eta_dot_j(k) - eta_dot_i(k)));
  };
  *a = Vec5Of(sum(0, e(0)), sum(1, e(1)), sum(2, e(2)), sum(3, WrapAngle(e(3))),
              sum(4, WrapAngle(e(4))));
}

/// Protocol (10) with formation offsets (docs/examples.md, "Outer loop"):
///   a_i = sum_j a_ij [k1((eta_j - d_j) - (eta_i - d_i)) + k2(eta_dot_j - eta_dot_i)]
/// every term at the neighbour's send time t - tau_ij, angle differences wrapped.
inline Vec5 Protocol10(double k1, double k2, const Vec5& offset_i, const NeighbourTerm* terms,
                       int count) {
  Vec5 a = Vec5::Zero();
  for (int k = 0; k < count; ++k) {
    const NeighbourTerm& t = terms[k];
    AddProtocol10Term(k1, k2, offset_i, t.weight, t.eta_j, t.eta_dot_j, t.offset_j, t.eta_i,
                      t.eta_dot_i, &a);
  }
  return a;
}

/// Feedback linearisation (Fossen-model inverse dynamics):
///   tau = M J^{-1}(a - J_dot nu) + C(nu) nu + D(nu) nu + g(eta)
/// so that, without saturation and disturbance, eta'' = a.
inline Vec5 FeedbackLinearise(const FossenModel& model, const Vec5& eta, const Vec5& nu,
                              const Vec5& a) {
  const Vec5 nu_dot = FossenModel::JInv(eta) * (a - FossenModel::JDotNu(eta, nu));
  return model.M() * nu_dot + model.C(nu) * nu + model.DampingForce(nu) +
         model.Restoring(eta);
}

inline double Clip(double v, double lim) { return v > lim ? lim : (v < -lim ? -lim : v); }

/// True if the saturated force tau differs from the demand beyond rounding.
inline bool SaturationChanged(const Vec5& tau, const Vec5& demand) {
  return (tau - demand).cwiseAbs().maxCoeff() > 1e-12 * (1.0 + demand.cwiseAbs().maxCoeff());
}

/// Saturated feedback linearisation. Translation saturates first and attitude keeps its
/// authority: the forces X, Y, Z are clipped to their limits, then the moments M, N are
/// recomputed from M's coupled 2x2 blocks (w, q) and (v, r) with the heave and sway
/// accelerations that the clipped forces will actually produce, so that the pitch and yaw
/// channels still get q_dot and r_dot as commanded unless M or N saturate themselves.
/// (Clipping every channel independently asks the moments to compensate translational
/// accelerations that the clipped forces never produce, which destabilises pitch.)
/// Without clipping this equals FeedbackLinearise(). Returns true if any channel differs
/// from the unsaturated demand; the unsaturated demand goes to *wanted if non-null.
inline bool SaturatedFeedbackLinearise(const FossenModel& model, const AttitudeTrig<double>& c,
                                       const Vec5& nu, const Vec5& a, const Vec5& tau_max,
                                       Vec5* tau, Vec5* wanted = nullptr) {
  const Vec5 nd = FossenModel::JInvTimes(c, a - FossenModel::JDotNu(c, nu));
  Vec5 n = model.CoriolisForce(nu) + model.DampingForce(nu);
  n(3) += model.params().W * model.params().z_g * c.st;  // g(eta)
  const Mat5& M = model.M();
  const Vec5 demand = model.MTimes(nd) + n;
  Vec5& t = *tau;
  t(0) = Clip(demand(0), tau_max(0));
  t(1) = Clip(demand(1), tau_max(1));
  t(2) = Clip(demand(2), tau_max(2));
  const double w_dot = (t(2) - n(2) - M(2, 3) * nd(3)) / M(2, 2);
  t(3) = Clip(M(3, 2) * w_dot + M(3, 3) * nd(3) + n(3), tau_max(3));
  const double v_dot = (t(1) - n(1) - M(1, 4) * nd(4)) / M(1, 1);
  t(4) = Clip(M(4, 1) * v_dot + M(4, 4) * nd(4) + n(4), tau_max(4));
  if (wanted) *wanted = demand;
  return SaturationChanged(t, demand);
}
inline bool SaturatedFeedbackLinearise(const FossenModel& model, const Vec5& eta, const Vec5& nu,
                                       const Vec5& a, const Vec5& tau_max, Vec5* tau,
                                       Vec5* wanted = nullptr) {
  return SaturatedFeedbackLinearise(model, AttitudeTrig<double>(eta), nu, a, tau_max, tau, wanted);
}

/// One vehicle's SaturatedFeedbackLinearise call, for SaturatedFeedbackLineariseMany.
struct ForceJob {
  AttitudeTrig<double> trig{Vec5::Zero()};  // of eta
  Vec5 nu = Vec5::Zero();
  Vec5 a = Vec5::Zero();
  Vec5 tau_max = Vec5::Zero();
  Vec5 tau = Vec5::Zero();     // out: the saturated force
  Vec5 wanted = Vec5::Zero();  // out: the unsaturated demand
  bool saturated = false;      // out: SaturatedFeedbackLinearise's result
};

/// SaturatedFeedbackLinearise for every job, all with the same model, four at a time in
/// vector lanes (core/fossen_lanes.h): every result has the bits the scalar function
/// gives it (tests/unit/control_test.cc).
void SaturatedFeedbackLineariseMany(const FossenModel& model, ForceJob* const* jobs, int count,
                                    LaneCode lanes = LaneCode::kBest);

/// Clips each channel of tau to [-tau_max, tau_max]; returns true if any was clipped.
inline bool Saturate(const Vec5& tau_max, Vec5* tau) {
  bool clipped = false;
  for (int k = 0; k < 5; ++k) {
    const double c = Clip((*tau)(k), tau_max(k));
    clipped |= c != (*tau)(k);
    (*tau)(k) = c;
  }
  return clipped;
}

}  // namespace shoal

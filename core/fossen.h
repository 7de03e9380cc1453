// Fossen 5-DOF UUV model (roll ignored) with REMUS 100 parameters.
//   eta_dot = J(eta) nu,   M nu_dot + C(nu_r) nu_r + D(nu_r) nu_r + g(eta) = tau
// eta = [x y z theta psi] (NED), nu = [u v w q r] (body), nu_r = nu - nu_c (current).
// Functions are templated on the scalar so that Ceres can differentiate through them
// (model identification); the double instantiations are what the simulator runs.
#pragma once

#include <cmath>

#include "core/types.h"

namespace shoal {

template <typename T>
using Vec5T = Eigen::Matrix<T, 5, 1>;
template <typename T>
using Mat5T = Eigen::Matrix<T, 5, 5>;

/// sin/cos of pitch and heading, computed once and shared by J, J^{-1}, J_dot nu.
template <typename T>
struct AttitudeTrig {
  T ct, st, cp, sp;
  AttitudeTrig(T cos_theta, T sin_theta, T cos_psi, T sin_psi)
      : ct(cos_theta), st(sin_theta), cp(cos_psi), sp(sin_psi) {}
  explicit AttitudeTrig(const Vec5T<T>& eta) {
    using std::cos;
    using std::sin;
    ct = cos(eta(3));
    st = sin(eta(3));
    cp = cos(eta(4));
    sp = sin(eta(4));
  }
};

/// sin/cos of (a + d) from sin/cos of a for a small increment d: angle addition with
/// Taylor series of sin d, cos d to order 9 (truncation below 3e-18 for |d| <= 0.05).
/// Falls back to std::sin/cos of a + d for larger increments.
inline void ShiftAngle(double a, double sa, double ca, double d, double* s_out, double* c_out) {
  if (std::abs(d) > 0.05) {
    *s_out = std::sin(a + d);
    *c_out = std::cos(a + d);
    return;
  }
  // Horner form in the Taylor coefficients, multiplied rather than divided: a division
  // costs the latency of several multiplications, and ShiftTrig runs 16 of these series
  // per RK4 step.
  constexpr double s3 = 1.0 / 6.0, s5 = 1.0 / 120.0, s7 = 1.0 / 5040.0, s9 = 1.0 / 362880.0;
  constexpr double c2 = 0.5, c4 = 1.0 / 24.0, c6 = 1.0 / 720.0, c8 = 1.0 / 40320.0;
  const double d2 = d * d;
  const double sd = d - d * d2 * (s3 - d2 * (s5 - d2 * (s7 - d2 * s9)));
  const double cd = 1.0 - d2 * (c2 - d2 * (c4 - d2 * (c6 - d2 * c8)));
  *s_out = sa * cd + ca * sd;
  *c_out = ca * cd - sa * sd;
}

/// Trig of eta_new from the trig of a nearby eta_base (RK4 stages, a few ms apart).
inline AttitudeTrig<double> ShiftTrig(const AttitudeTrig<double>& base, const Vec5& eta_base,
                                      const Vec5& eta_new) {
  AttitudeTrig<double> t = base;
  ShiftAngle(eta_base(3), base.st, base.ct, eta_new(3) - eta_base(3), &t.st, &t.ct);
  ShiftAngle(eta_base(4), base.sp, base.cp, eta_new(4) - eta_base(4), &t.sp, &t.cp);
  return t;
}

/// REMUS 100 (Prestero 2001, MIT/WHOI thesis); SI units. See docs/reference.md.
///
/// The hydrodynamic forces are Prestero's nonlinear model: axial and cross-flow drag
/// quadratic in the velocities, plus body and fin lift proportional to u. His linear
/// table (X_u = -13.5 kg/s, Z_w = -66.6 kg/s, M_q = -6.87 kg m^2/s at 1.54 m/s) is the
/// linearisation of these same forces about cruise, not extra damping: adding it to the
/// quadratic terms would count the drag twice (about 24 N of surge drag at 1.5 m/s
/// against the 3.86 N cruise thrust). The added-mass Munk terms are in C(nu).
struct RemusParams {
  double m = 30.48;    // kg
  double W = 299.0;    // N, weight (= buoyancy B)
  double z_g = 0.0196; // m, CG below CB
  double I_y = 3.45;   // kg m^2
  double I_z = 3.45;   // kg m^2
  // Added mass.
  double X_udot = -0.93, Y_vdot = -35.5, Z_wdot = -35.5;
  double M_qdot = -4.88, N_rdot = -4.88;
  double Y_rdot = 1.93, Z_qdot = -1.93, M_wdot = -1.93, N_vdot = 1.93;
  // Quadratic drag: X_u|u| (kg/m), Y_v|v| = Z_w|w| (kg/m), M_q|q| = N_r|r| (kg m^2/rad^2).
  double X_uu = -1.62, Y_vv = -131.0, Z_ww = -131.0, M_qq = -9.40, N_rr = -9.40;
  // Lift of the hull and the fins, proportional to u (forward motion), derived from
  // Prestero's formulas and geometry (docs/reference.md): heave/pitch (w, q) and, by
  // axisymmetry, sway/yaw (v, r). Z_uw, Y_uv in kg/m; Z_uq, Y_ur in kg/rad; M_uw, N_uv
  // in kg; M_uq, N_ur in kg m/rad.
  double Z_uw = -33.23, Z_uq = -7.295, M_uw = -14.53, M_uq = -4.980;
  double Y_uv = -33.23, Y_ur = 7.295, N_uv = 14.53, N_ur = -4.980;
};

/// Rigid-body + added-mass inertia (Fossen 2011; paper Sec. II-B with m52 = -N_vdot so
/// that M = M^T, docs/reference.md errata).
inline Mat5 MassMatrix(const RemusParams& p) {
  Mat5 M = Mat5::Zero();
  M(0, 0) = p.m - p.X_udot;
  M(1, 1) = p.m - p.Y_vdot;
  M(1, 4) = -p.Y_rdot;
  M(2, 2) = p.m - p.Z_wdot;
  M(2, 3) = -p.Z_qdot;
  M(3, 2) = -p.M_wdot;
  M(3, 3) = p.I_y - p.M_qdot;
  M(4, 1) = -p.N_vdot;
  M(4, 4) = p.I_z - p.N_rdot;
  return M;
}

/// The model with its constant matrices precomputed.
class FossenModel {
 public:
  explicit FossenModel(const RemusParams& p = RemusParams())
      : p_(p), M_(MassMatrix(p)), M_inv_(M_.inverse()) {
    m11_ = M_(0, 0);
    m22_ = M_(1, 1);
    m33_ = M_(2, 2);
    mb34_ = -(p.Z_qdot + p.M_wdot) / 2.0;
    mb25_ = -(p.Y_rdot + p.N_vdot) / 2.0;
    wzg_ = p.W * p.z_g;
  }

  const RemusParams& params() const { return p_; }
  const Mat5& M() const { return M_; }
  const Mat5& M_inv() const { return M_inv_; }

  /// Coriolis-centripetal matrix C(nu) with the paper's sign errors corrected
  /// (docs/reference.md): skew-symmetric, so nu^T C(nu) nu = 0.
  template <typename T>
  Mat5T<T> C(const Vec5T<T>& nu) const {
    const T u = nu(0), v = nu(1), w = nu(2), q = nu(3), r = nu(4);
    const T a = T(m33_) * w + T(mb34_) * q;
    const T b = T(m22_) * v + T(mb25_) * r;
    const T c = T(m11_) * u;
    Mat5T<T> C = Mat5T<T>::Zero();
    C(0, 3) = a;
    C(0, 4) = -b;
    C(1, 4) = c;
    C(2, 3) = -c;
    C(3, 0) = -a;
    C(3, 2) = c;
    C(4, 0) = b;
    C(4, 1) = -c;
    return C;
  }

  /// C(nu) nu, written out (C has 8 non-zero entries).
  template <typename T>
  Vec5T<T> CoriolisForce(const Vec5T<T>& nu) const {
    const T u = nu(0), v = nu(1), w = nu(2), q = nu(3), r = nu(4);
    const T a = T(m33_) * w + T(mb34_) * q;
    const T b = T(m22_) * v + T(mb25_) * r;
    const T c = T(m11_) * u;
    Vec5T<T> f;
    f(0) = a * q - b * r;
    f(1) = c * r;
    f(2) = -c * q;
    f(3) = -a * u + c * w;
    f(4) = b * u - c * v;
    return f;
  }

  /// M^{-1} x using M's block structure: (u), (v, r), (w, q).
  template <typename T>
  Vec5T<T> SolveM(const Vec5T<T>& x) const {
    const Mat5& Mi = M_inv_;
    Vec5T<T> y;
    y(0) = T(Mi(0, 0)) * x(0);
    y(1) = T(Mi(1, 1)) * x(1) + T(Mi(1, 4)) * x(4);
    y(4) = T(Mi(4, 1)) * x(1) + T(Mi(4, 4)) * x(4);
    y(2) = T(Mi(2, 2)) * x(2) + T(Mi(2, 3)) * x(3);
    y(3) = T(Mi(3, 2)) * x(2) + T(Mi(3, 3)) * x(3);
    return y;
  }

  /// D(nu) nu, minus Prestero's drag and lift forces (docs/reference.md):
  ///   X = X_u|u| |u| u
  ///   Y = Y_v|v| |v| v + u (Y_uv v + Y_ur r),   N = N_r|r| |r| r + u (N_uv v + N_ur r)
  ///   Z = Z_w|w| |w| w + u (Z_uw w + Z_uq q),   M = M_q|q| |q| q + u (M_uw w + M_uq q)
  /// For u >= 0 it dissipates energy (nu^T D(nu) nu >= 0). The lift terms are Prestero's
  /// model of forward motion; going astern (u < 0) they feed energy in, and the model is
  /// not meant for long runs astern.
  template <typename T>
  Vec5T<T> DampingForce(const Vec5T<T>& nu) const {
    using std::abs;
    const T u = nu(0), v = nu(1), w = nu(2), q = nu(3), r = nu(4);
    Vec5T<T> d;
    d(0) = -T(p_.X_uu) * abs(u) * u;
    d(1) = -(T(p_.Y_vv) * abs(v) * v + u * (T(p_.Y_uv) * v + T(p_.Y_ur) * r));
    d(2) = -(T(p_.Z_ww) * abs(w) * w + u * (T(p_.Z_uw) * w + T(p_.Z_uq) * q));
    d(3) = -(T(p_.M_qq) * abs(q) * q + u * (T(p_.M_uw) * w + T(p_.M_uq) * q));
    d(4) = -(T(p_.N_rr) * abs(r) * r + u * (T(p_.N_uv) * v + T(p_.N_ur) * r));
    return d;
  }

  /// Restoring forces with W = B, CO at CB: g(eta) = [0 0 0 W z_g sin(theta) 0].
  template <typename T>
  Vec5T<T> Restoring(const Vec5T<T>& eta) const {
    using std::sin;
    Vec5T<T> g = Vec5T<T>::Zero();
    g(3) = T(wzg_) * sin(eta(3));
    return g;
  }

  /// Potential energy of the restoring moment, W z_g (1 - cos theta).
  double PotentialEnergy(const Vec5& eta) const { return wzg_ * (1.0 - std::cos(eta(3))); }

  /// Kinematics J(eta) = blockdiag(R_z(psi) R_y(theta), diag(1, 1/cos theta)).
  template <typename T>
  static Mat5T<T> J(const AttitudeTrig<T>& c) {
    Mat5T<T> J = Mat5T<T>::Zero();
    J(0, 0) = c.cp * c.ct; J(0, 1) = -c.sp; J(0, 2) = c.cp * c.st;
    J(1, 0) = c.sp * c.ct; J(1, 1) = c.cp;  J(1, 2) = c.sp * c.st;
    J(2, 0) = -c.st;       J(2, 1) = T(0);  J(2, 2) = c.ct;
    J(3, 3) = T(1);
    J(4, 4) = T(1) / c.ct;
    return J;
  }
  template <typename T>
  static Mat5T<T> J(const Vec5T<T>& eta) { return J(AttitudeTrig<T>(eta)); }

  /// J^{-1}(eta) = blockdiag(R^T, diag(1, cos theta)) (docs/reference.md).
  template <typename T>
  static Mat5T<T> JInv(const AttitudeTrig<T>& c) {
    Mat5T<T> Ji = Mat5T<T>::Zero();
    Ji(0, 0) = c.cp * c.ct; Ji(0, 1) = c.sp * c.ct; Ji(0, 2) = -c.st;
    Ji(1, 0) = -c.sp;       Ji(1, 1) = c.cp;        Ji(1, 2) = T(0);
    Ji(2, 0) = c.cp * c.st; Ji(2, 1) = c.sp * c.st; Ji(2, 2) = c.ct;
    Ji(3, 3) = T(1);
    Ji(4, 4) = c.ct;
    return Ji;
  }
  template <typename T>
  static Mat5T<T> JInv(const Vec5T<T>& eta) { return JInv(AttitudeTrig<T>(eta)); }

  /// J^{-1}(eta) x without forming the matrix: its non-zero entries, each row summed in
  /// column order as the dense product does (so the result is the same to the bit).
  static Vec5 JInvTimes(const AttitudeTrig<double>& c, const Vec5& x) {
    Vec5 y;
    y(0) = c.cp * c.ct * x(0) + c.sp * c.ct * x(1) + -c.st * x(2);
    y(1) = -c.sp * x(0) + c.cp * x(1);
    y(2) = c.cp * c.st * x(0) + c.sp * c.st * x(1) + c.ct * x(2);
    y(3) = x(3);
    y(4) = c.ct * x(4);
    return y;
  }

  /// M x using M's structure (the 2x2 blocks (v, r) and (w, q)), rows summed in column
  /// order as the dense product does.
  Vec5 MTimes(const Vec5& x) const {
    Vec5 y;
    y(0) = M_(0, 0) * x(0);
    y(1) = M_(1, 1) * x(1) + M_(1, 4) * x(4);
    y(2) = M_(2, 2) * x(2) + M_(2, 3) * x(3);
    y(3) = M_(3, 2) * x(2) + M_(3, 3) * x(3);
    y(4) = M_(4, 1) * x(1) + M_(4, 4) * x(4);
    return y;
  }

  /// eta_dot = J(eta) nu, without forming J.
  template <typename T>
  static Vec5T<T> EtaDot(const AttitudeTrig<T>& c, const Vec5T<T>& nu) {
    Vec5T<T> d;
    EtaDotTo(c, nu, &d);
    return d;
  }
  /// The same, written into *d: where it is to be stored (a copy of a vector just written
  /// element by element, read by wide loads, waits for the stores to reach the cache).
  template <typename T>
  static void EtaDotTo(const AttitudeTrig<T>& c, const Vec5T<T>& nu, Vec5T<T>* d) {
    const T u = nu(0), v = nu(1), w = nu(2);
    (*d)(0) = c.cp * c.ct * u - c.sp * v + c.cp * c.st * w;
    (*d)(1) = c.sp * c.ct * u + c.cp * v + c.sp * c.st * w;
    (*d)(2) = -c.st * u + c.ct * w;
    (*d)(3) = nu(3);
    (*d)(4) = nu(4) / c.ct;
  }
  template <typename T>
  static Vec5T<T> EtaDot(const Vec5T<T>& eta, const Vec5T<T>& nu) {
    return EtaDot(AttitudeTrig<T>(eta), nu);
  }

  /// J_dot(eta, nu) nu, with theta_dot = q and psi_dot = r / cos(theta).
  template <typename T>
  static Vec5T<T> JDotNu(const AttitudeTrig<T>& c, const Vec5T<T>& nu) {
    const T ct = c.ct, st = c.st, cp = c.cp, sp = c.sp;
    const T u = nu(0), v = nu(1), w = nu(2), q = nu(3), r = nu(4);
    const T thd = q, psd = r / ct;
    // dR/dtheta * [u v w] and dR/dpsi * [u v w].
    const T rt0 = -cp * st * u + cp * ct * w;
    const T rt1 = -sp * st * u + sp * ct * w;
    const T rt2 = -ct * u - st * w;
    const T rp0 = -sp * ct * u - cp * v - sp * st * w;
    const T rp1 = cp * ct * u - sp * v + cp * st * w;
    Vec5T<T> out;
    out(0) = rt0 * thd + rp0 * psd;
    out(1) = rt1 * thd + rp1 * psd;
    out(2) = rt2 * thd;
    out(3) = T(0);
    out(4) = r * st * thd / (ct * ct);
    return out;
  }
  template <typename T>
  static Vec5T<T> JDotNu(const Vec5T<T>& eta, const Vec5T<T>& nu) {
    return JDotNu(AttitudeTrig<T>(eta), nu);
  }

  /// nu_dot = M^{-1} (tau - C(nu_r) nu_r - D(nu_r) nu_r - g(eta)), nu_r = nu - nu_c.
  template <typename T>
  Vec5T<T> NuDot(const AttitudeTrig<T>& c, const Vec5T<T>& nu, const Vec5T<T>& tau,
                 const Vec5T<T>& nu_c) const {
    const Vec5T<T> nu_r = nu - nu_c;
    Vec5T<T> rhs = tau - CoriolisForce(nu_r) - DampingForce(nu_r);
    rhs(3) -= T(wzg_) * c.st;  // g(eta)
    return SolveM(rhs);
  }
  template <typename T>
  Vec5T<T> NuDot(const Vec5T<T>& eta, const Vec5T<T>& nu, const Vec5T<T>& tau,
                 const Vec5T<T>& nu_c) const {
    return NuDot(AttitudeTrig<T>(eta), nu, tau, nu_c);
  }

  /// Kinetic + restoring potential energy, 1/2 nu^T M nu + W z_g (1 - cos theta).
  double Energy(const Vec5& eta, const Vec5& nu) const {
    return 0.5 * nu.dot(M_ * nu) + PotentialEnergy(eta);
  }

 private:
  friend class FossenLanes;  // the same arithmetic in vector lanes (core/fossen_lanes.h)
  RemusParams p_;
  Mat5 M_;
  Mat5 M_inv_;
  double m11_ = 0, m22_ = 0, m33_ = 0, mb34_ = 0, mb25_ = 0, wzg_ = 0;
};

/// Plant state of one vehicle.
struct PlantState {
  Vec5 eta = Vec5::Zero();
  Vec5 nu = Vec5::Zero();
};

/// Body-frame current velocity nu_c = [R^T v_c; 0; 0] for an earth-frame current v_c.
inline Vec5 BodyCurrent(const AttitudeTrig<double>& c, const Vec3& v_c_ned) {
  Vec5 nu_c = Vec5::Zero();
  if (v_c_ned.isZero()) return nu_c;
  nu_c.head<3>() = FossenModel::JInv(c).topLeftCorner<3, 3>() * v_c_ned;
  return nu_c;
}
inline Vec5 BodyCurrent(const Vec5& eta, const Vec3& v_c_ned) {
  return BodyCurrent(AttitudeTrig<double>(eta), v_c_ned);
}

/// Classic RK4 over [t, t + dt] with tau and the earth-frame current held constant.
/// `trig` must be AttitudeTrig(x->eta); the stages' trig comes from it by ShiftTrig().
void Rk4Step(const FossenModel& model, const Vec5& tau, const Vec3& current_ned, double dt,
             const AttitudeTrig<double>& trig, PlantState* x,
             AttitudeTrig<double>* trig_out = nullptr);

/// Integrates over `period_s` in `substeps` equal RK4 steps. `trig`, if given, must be
/// AttitudeTrig(x->eta) (the caller usually has it already).
/// `trig_out`, if given, receives the trig of the final state, by ShiftTrig from the last
/// step's (equal to AttitudeTrig(x->eta) to rounding).
void Integrate(const FossenModel& model, const Vec5& tau, const Vec3& current_ned,
               double period_s, int substeps, PlantState* x,
               const AttitudeTrig<double>* trig = nullptr,
               AttitudeTrig<double>* trig_out = nullptr);

/// One vehicle's Integrate() call, for IntegrateMany.
struct PlantJob {
  PlantState* x = nullptr;
  Vec5 tau = Vec5::Zero();
  Vec3 current_ned = Vec3::Zero();
  const AttitudeTrig<double>* trig = nullptr;  // AttitudeTrig(x->eta), or null
  AttitudeTrig<double>* trig_out = nullptr;
};

/// Integrate() for every job, all with the same model, period and substeps. Vehicles in
/// still water are stepped four at a time in vector lanes (core/fossen_lanes.h); every
/// result has the bits Integrate() gives it alone.
/// `lanes`: which vector code steps the lanes: kBest is the CPU's best of AVX-512 (eight
/// lanes), AVX2 (four) and SSE2 (four, in pairs); every choice gives the same bits
/// (tests/unit: each against Integrate()).
enum class LaneCode { kBest, kAvx512, kAvx2, kBase };
/// kBest: the CPU's best code; any other: itself.
LaneCode BestLaneCode(LaneCode asked);
/// True if this CPU can run `code`.
bool CpuRuns(LaneCode code);
void IntegrateMany(const FossenModel& model, double period_s, int substeps, PlantJob* jobs,
                   int count, LaneCode lanes = LaneCode::kBest);

}  // namespace shoal

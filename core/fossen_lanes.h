// The still-water RK4 step of the Fossen model (core/fossen.h) written once over a "lane"
// type L: a double, or a GCC vector of four (eight) doubles that steps four (eight)
// vehicles at once.
// Every lane performs exactly the operations of the double version, in the same order
// (IEEE arithmetic is the same in a vector lane as in a scalar register, and the core is
// built with -ffp-contract=off so that no build fuses a multiply and an add differently),
// so a vehicle stepped in a lane and one stepped alone end with the same bits.
#pragma once

#include <cmath>
#include <cstdint>

#include "core/fossen.h"

// Every function taking or returning Lanes4 is inlined into its caller, so GCC's note that
// a 32-byte vector is passed differently with and without AVX concerns no call made. (Only
// the core's lane code includes this header, core/fossen.cc and control.cc, and the note
// comes with the templates' instances at the end of those files: the pragma stays in
// force.)
#pragma GCC diagnostic ignored "-Wpsabi"

namespace shoal {

using Lanes4 = double __attribute__((vector_size(32)));
using Lanes8 = double __attribute__((vector_size(64)));

namespace lanes {

using Mask4 = std::int64_t __attribute__((vector_size(32)));
using Mask8 = std::int64_t __attribute__((vector_size(64)));

inline double Abs(double x) { return std::fabs(x); }
[[gnu::always_inline]] inline Lanes4 Abs(Lanes4 x) {
  const Mask4 magnitude = {INT64_MAX, INT64_MAX, INT64_MAX, INT64_MAX};
  return reinterpret_cast<Lanes4>(reinterpret_cast<Mask4>(x) & magnitude);
}
[[gnu::always_inline]] inline Lanes8 Abs(Lanes8 x) {
  const Mask8 magnitude = {INT64_MAX, INT64_MAX, INT64_MAX, INT64_MAX,
                           INT64_MAX, INT64_MAX, INT64_MAX, INT64_MAX};
  return reinterpret_cast<Lanes8>(reinterpret_cast<Mask8>(x) & magnitude);
}

template <typename L>
struct Count;
template <>
struct Count<double> {
  static constexpr int kLanes = 1;
};
template <>
struct Count<Lanes4> {
  static constexpr int kLanes = 4;
};
template <>
struct Count<Lanes8> {
  static constexpr int kLanes = 8;
};

inline double& At(double& x, int) { return x; }
inline double At(const double& x, int) { return x; }
[[gnu::always_inline]] inline double At(const Lanes4& x, int i) { return x[i]; }
[[gnu::always_inline]] inline double At(const Lanes8& x, int i) { return x[i]; }
[[gnu::always_inline]] inline void Set(double* x, int, double v) { *x = v; }
[[gnu::always_inline]] inline void Set(Lanes4* x, int i, double v) { (*x)[i] = v; }
[[gnu::always_inline]] inline void Set(Lanes8* x, int i, double v) { (*x)[i] = v; }

/// The lanes f(0), f(1), ... of L, built in registers: a vector written lane by lane in
/// memory and then read whole stalls the CPU, which cannot forward narrow stores to a wide
/// load (a gather of a pack's states that way was a tenth of its integration).
template <typename L, typename F>
[[gnu::always_inline]] inline L Gather(F f) {
  if constexpr (Count<L>::kLanes == 1) {
    return f(0);
  } else if constexpr (Count<L>::kLanes == 4) {
    return L{f(0), f(1), f(2), f(3)};
  } else {
    return L{f(0), f(1), f(2), f(3), f(4), f(5), f(6), f(7)};
  }
}

inline double Clip(double v, double lim) { return v > lim ? lim : (v < -lim ? -lim : v); }
[[gnu::always_inline]] inline Lanes4 Clip(Lanes4 v, Lanes4 lim) {
  return v > lim ? lim : (v < -lim ? -lim : v);
}
[[gnu::always_inline]] inline Lanes8 Clip(Lanes8 v, Lanes8 lim) {
  return v > lim ? lim : (v < -lim ? -lim : v);
}

template <typename L>
struct Vec5L {
  L v[5];
};

template <typename L>
struct TrigL {
  L ct, st, cp, sp;
};

/// ShiftAngle (core/fossen.h) in every lane, with its fallback to std::sin/cos of a + d in
/// the lanes whose increment exceeds 0.05.
template <typename L>
[[gnu::always_inline]] inline void ShiftAngle(L a, L sa, L ca, L d, L* s_out, L* c_out) {
  if constexpr (Count<L>::kLanes == 1) {
    shoal::ShiftAngle(a, sa, ca, d, s_out, c_out);
  } else {
    constexpr double s3 = 1.0 / 6.0, s5 = 1.0 / 120.0, s7 = 1.0 / 5040.0, s9 = 1.0 / 362880.0;
    constexpr double c2 = 0.5, c4 = 1.0 / 24.0, c6 = 1.0 / 720.0, c8 = 1.0 / 40320.0;
    const L d2 = d * d;
    const L sd = d - d * d2 * (s3 - d2 * (s5 - d2 * (s7 - d2 * s9)));
    const L cd = 1.0 - d2 * (c2 - d2 * (c4 - d2 * (c6 - d2 * c8)));
    *s_out = sa * cd + ca * sd;
    *c_out = ca * cd - sa * sd;
    for (int i = 0; i < Count<L>::kLanes; ++i) {
      if (std::abs(d[i]) > 0.05) {
        Set(s_out, i, std::sin(a[i] + d[i]));
        Set(c_out, i, std::cos(a[i] + d[i]));
      }
    }
  }
}

template <typename L>
[[gnu::always_inline]] inline TrigL<L> ShiftTrig(const TrigL<L>& base, const Vec5L<L>& eta_base,
                                                 const Vec5L<L>& eta_new) {
  TrigL<L> t = base;
  ShiftAngle(eta_base.v[3], base.st, base.ct, eta_new.v[3] - eta_base.v[3], &t.st, &t.ct);
  ShiftAngle(eta_base.v[4], base.sp, base.cp, eta_new.v[4] - eta_base.v[4], &t.sp, &t.cp);
  return t;
}

/// FossenModel::EtaDot, term for term.
template <typename L>
[[gnu::always_inline]] inline Vec5L<L> EtaDot(const TrigL<L>& c, const Vec5L<L>& nu) {
  const L u = nu.v[0], v = nu.v[1], w = nu.v[2];
  Vec5L<L> d;
  d.v[0] = c.cp * c.ct * u - c.sp * v + c.cp * c.st * w;
  d.v[1] = c.sp * c.ct * u + c.cp * v + c.sp * c.st * w;
  d.v[2] = -c.st * u + c.ct * w;
  d.v[3] = nu.v[3];
  d.v[4] = nu.v[4] / c.ct;
  return d;
}

}  // namespace lanes

/// FossenModel::NuDotStill and the RK4 step in lanes (the model's constants are shared by
/// every lane: vehicles stepped together have the same model).
class FossenLanes {
 public:
  explicit FossenLanes(const FossenModel& m) : m_(m) {}

  template <typename L>
  [[gnu::always_inline]] lanes::Vec5L<L> NuDotStill(const lanes::TrigL<L>& c,
                                                    const lanes::Vec5L<L>& nu,
                                                    const lanes::Vec5L<L>& tau) const {
    using lanes::Abs;
    const RemusParams& p = m_.p_;
    const L u = nu.v[0], v = nu.v[1], w = nu.v[2], q = nu.v[3], r = nu.v[4];
    // CoriolisForce.
    const L a = m_.m33_ * w + m_.mb34_ * q;
    const L b = m_.m22_ * v + m_.mb25_ * r;
    const L cu = m_.m11_ * u;
    // DampingForce.
    const L d0 = -p.X_uu * Abs(u) * u;
    const L d1 = -(p.Y_vv * Abs(v) * v + u * (p.Y_uv * v + p.Y_ur * r));
    const L d2 = -(p.Z_ww * Abs(w) * w + u * (p.Z_uw * w + p.Z_uq * q));
    const L d3 = -(p.M_qq * Abs(q) * q + u * (p.M_uw * w + p.M_uq * q));
    const L d4 = -(p.N_rr * Abs(r) * r + u * (p.N_uv * v + p.N_ur * r));
    lanes::Vec5L<L> rhs;
    rhs.v[0] = tau.v[0] - (a * q - b * r) - d0;
    rhs.v[1] = tau.v[1] - cu * r - d1;
    rhs.v[2] = tau.v[2] - -cu * q - d2;
    rhs.v[3] = tau.v[3] - (-a * u + cu * w) - d3;
    rhs.v[4] = tau.v[4] - (b * u - cu * v) - d4;
    rhs.v[3] -= m_.wzg_ * c.st;
    // SolveM.
    const Mat5& Mi = m_.M_inv_;
    lanes::Vec5L<L> y;
    y.v[0] = Mi(0, 0) * rhs.v[0];
    y.v[1] = Mi(1, 1) * rhs.v[1] + Mi(1, 4) * rhs.v[4];
    y.v[4] = Mi(4, 1) * rhs.v[1] + Mi(4, 4) * rhs.v[4];
    y.v[2] = Mi(2, 2) * rhs.v[2] + Mi(2, 3) * rhs.v[3];
    y.v[3] = Mi(3, 2) * rhs.v[2] + Mi(3, 3) * rhs.v[3];
    return y;
  }

  /// SaturatedFeedbackLinearise (core/control.h), term for term: *tau receives the
  /// saturated force, *demand the unsaturated one.
  template <typename L>
  [[gnu::always_inline]] void SaturatedFeedbackLinearise(
      const lanes::TrigL<L>& c, const lanes::Vec5L<L>& nu, const lanes::Vec5L<L>& acc,
      const lanes::Vec5L<L>& tau_max, lanes::Vec5L<L>* tau, lanes::Vec5L<L>* demand) const {
    using lanes::Clip;
    const L ct = c.ct, st = c.st, cp = c.cp, sp = c.sp;
    const L u = nu.v[0], v = nu.v[1], w = nu.v[2], q = nu.v[3], r = nu.v[4];
    // x = acc - J_dot(eta, nu) nu (FossenModel::JDotNu).
    const L thd = q, psd = r / ct;
    const L rt0 = -cp * st * u + cp * ct * w;
    const L rt1 = -sp * st * u + sp * ct * w;
    const L rt2 = -ct * u - st * w;
    const L rp0 = -sp * ct * u - cp * v - sp * st * w;
    const L rp1 = cp * ct * u - sp * v + cp * st * w;
    const L x0 = acc.v[0] - (rt0 * thd + rp0 * psd);
    const L x1 = acc.v[1] - (rt1 * thd + rp1 * psd);
    const L x2 = acc.v[2] - rt2 * thd;
    const L x3 = acc.v[3] - 0.0;
    const L x4 = acc.v[4] - r * st * thd / (ct * ct);
    // nd = J^{-1}(eta) x (FossenModel::JInvTimes).
    const L nd0 = cp * ct * x0 + sp * ct * x1 + -st * x2;
    const L nd1 = -sp * x0 + cp * x1;
    const L nd2 = cp * st * x0 + sp * st * x1 + ct * x2;
    const L nd3 = x3;
    const L nd4 = ct * x4;
    // n = C(nu) nu + D(nu) nu + g(eta).
    const RemusParams& p = m_.p_;
    const L a = m_.m33_ * w + m_.mb34_ * q;
    const L b = m_.m22_ * v + m_.mb25_ * r;
    const L cu = m_.m11_ * u;
    using lanes::Abs;
    const L n0 = (a * q - b * r) + -p.X_uu * Abs(u) * u;
    const L n1 = cu * r + -(p.Y_vv * Abs(v) * v + u * (p.Y_uv * v + p.Y_ur * r));
    const L n2 = -cu * q + -(p.Z_ww * Abs(w) * w + u * (p.Z_uw * w + p.Z_uq * q));
    const L n3 = (-a * u + cu * w) + -(p.M_qq * Abs(q) * q + u * (p.M_uw * w + p.M_uq * q)) +
                 p.W * p.z_g * st;
    const L n4 = (b * u - cu * v) + -(p.N_rr * Abs(r) * r + u * (p.N_uv * v + p.N_ur * r));
    // demand = M nd + n (FossenModel::MTimes), then translation first, attitude after.
    const Mat5& M = m_.M_;
    lanes::Vec5L<L>& d = *demand;
    d.v[0] = M(0, 0) * nd0 + n0;
    d.v[1] = (M(1, 1) * nd1 + M(1, 4) * nd4) + n1;
    d.v[2] = (M(2, 2) * nd2 + M(2, 3) * nd3) + n2;
    d.v[3] = (M(3, 2) * nd2 + M(3, 3) * nd3) + n3;
    d.v[4] = (M(4, 1) * nd1 + M(4, 4) * nd4) + n4;
    lanes::Vec5L<L>& t = *tau;
    t.v[0] = Clip(d.v[0], tau_max.v[0]);
    t.v[1] = Clip(d.v[1], tau_max.v[1]);
    t.v[2] = Clip(d.v[2], tau_max.v[2]);
    const L w_dot = (t.v[2] - n2 - M(2, 3) * nd3) / M(2, 2);
    t.v[3] = Clip(M(3, 2) * w_dot + M(3, 3) * nd3 + n3, tau_max.v[3]);
    const L v_dot = (t.v[1] - n1 - M(1, 4) * nd4) / M(1, 1);
    t.v[4] = Clip(M(4, 1) * v_dot + M(4, 4) * nd4 + n4, tau_max.v[4]);
  }

  /// Rk4Step in still water: x_eta, x_nu are advanced by dt under tau; trig is the trig of
  /// x_eta, *trig_out (if non-null) receives that of the result.
  template <typename L>
  [[gnu::always_inline]] void Rk4Still(const lanes::Vec5L<L>& tau, double dt,
                                       const lanes::TrigL<L>& trig, lanes::Vec5L<L>* x_eta,
                                       lanes::Vec5L<L>* x_nu,
                                       lanes::TrigL<L>* trig_out) const {
    using lanes::EtaDot;
    using lanes::ShiftTrig;
    using V = lanes::Vec5L<L>;
    const V eta = *x_eta, nu = *x_nu;
    const double half = 0.5 * dt, sixth = dt / 6.0;
    const V e1 = EtaDot(trig, nu), n1 = NuDotStill(trig, nu, tau);
    V eta2, nu2;
    for (int k = 0; k < 5; ++k) {
      eta2.v[k] = eta.v[k] + half * e1.v[k];
      nu2.v[k] = nu.v[k] + half * n1.v[k];
    }
    const lanes::TrigL<L> t2 = ShiftTrig(trig, eta, eta2);
    const V e2 = EtaDot(t2, nu2), n2 = NuDotStill(t2, nu2, tau);
    V eta3, nu3;
    for (int k = 0; k < 5; ++k) {
      eta3.v[k] = eta.v[k] + half * e2.v[k];
      nu3.v[k] = nu.v[k] + half * n2.v[k];
    }
    const lanes::TrigL<L> t3 = ShiftTrig(trig, eta, eta3);
    const V e3 = EtaDot(t3, nu3), n3 = NuDotStill(t3, nu3, tau);
    V eta4, nu4;
    for (int k = 0; k < 5; ++k) {
      eta4.v[k] = eta.v[k] + dt * e3.v[k];
      nu4.v[k] = nu.v[k] + dt * n3.v[k];
    }
    const lanes::TrigL<L> t4 = ShiftTrig(trig, eta, eta4);
    const V e4 = EtaDot(t4, nu4), n4 = NuDotStill(t4, nu4, tau);
    for (int k = 0; k < 5; ++k) {
      x_eta->v[k] = eta.v[k] + sixth * (e1.v[k] + 2.0 * e2.v[k] + 2.0 * e3.v[k] + e4.v[k]);
      x_nu->v[k] = nu.v[k] + sixth * (n1.v[k] + 2.0 * n2.v[k] + 2.0 * n3.v[k] + n4.v[k]);
    }
    if (trig_out != nullptr) *trig_out = ShiftTrig(trig, eta, *x_eta);
  }

 private:
  const FossenModel& m_;
};

}  // namespace shoal

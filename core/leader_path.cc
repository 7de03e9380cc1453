#include "core/leader_path.h"

#include <cmath>
#include <limits>

#include "core/control.h"
#include "core/fossen.h"

namespace shoal {

LeaderPath::LeaderPath(const LeaderConfig& c) : c_(c) {
  if (c_.path == PathKind::kWaypoints) {
    double t = 0.0;
    const auto& w = c_.waypoints_m;
    for (std::size_t k = 0; k + 1 < w.size(); ++k) {
      seg_start_s_.push_back(t);
      t += (w[k + 1] - w[k]).norm() / c_.speed_mps;
    }
    if (c_.loop && w.size() >= 2) {
      seg_start_s_.push_back(t);
      t += (w.front() - w.back()).norm() / c_.speed_mps;
    }
    total_s_ = t;
  }
}

namespace {

// Paper Sec. IV: x0 = 60 cos(0.0022 pi t) + 25 sin(0.0011 pi t),
// y0 = 60 sin(0.0022 pi t) + 25 cos(0.0011 pi t), z0 = -0.12 t.
constexpr double kHelixWa = 0.0022 * kPi, kHelixWb = 0.0011 * kPi;

// The helix at t given cos and sin of kHelixWb t. kHelixWa is exactly 2 kHelixWb (a factor
// of two is exact in binary), so the faster pair follows from the slower by the
// double-angle formulas.
void HelixPoint(double t, double cb, double sb, Vec3* p, Vec3* v, Vec3* a) {
  const double wa = kHelixWa, wb = kHelixWb;
  const double sa = 2.0 * sb * cb, ca = (cb - sb) * (cb + sb);
  *p = Vec3(60 * ca + 25 * sb, 60 * sa + 25 * cb, -0.12 * t);
  *v = Vec3(-60 * wa * sa + 25 * wb * cb, 60 * wa * ca - 25 * wb * sb, -0.12);
  *a = Vec3(-60 * wa * wa * ca - 25 * wb * wb * sb, -60 * wa * wa * sa - 25 * wb * wb * cb, 0.0);
}

// The angle from direction (ax, ay) to (bx, by) when it is small (|tan| <= 0.05): the
// arctangent's series of cross / dot to the 11th power (truncation below 1e-18); NaN
// otherwise, for the caller to take atan2. The helix turns less than 0.01 rad a second.
double SmallTurn(double ax, double ay, double bx, double by) {
  const double dot = ax * bx + ay * by;
  const double r = (ax * by - ay * bx) / dot;
  if (!(dot > 0.0 && std::abs(r) <= 0.05)) return std::numeric_limits<double>::quiet_NaN();
  constexpr double a3 = 1.0 / 3.0, a5 = 1.0 / 5.0, a7 = 1.0 / 7.0, a9 = 1.0 / 9.0,
                   a11 = 1.0 / 11.0;
  const double r2 = r * r;
  return r - r * r2 * (a3 - r2 * (a5 - r2 * (a7 - r2 * (a9 - r2 * a11))));
}

// The attitude (psi unwrapped, theta) of a path point whose velocity is v, horizontal speed
// h > 1e-9: from the anchor's by the turn since it, where the anchor has one.
void Attitude(const Vec3& v, double h, const LeaderPath::HelixAnchor* an, double* psi,
              double* theta) {
  if (an != nullptr && an->h > 1e-9) {
    const double dpsi = SmallTurn(an->v.x(), an->v.y(), v.x(), v.y());
    const double dtheta = SmallTurn(an->h, -an->v.z(), h, -v.z());
    if (!std::isnan(dpsi) && !std::isnan(dtheta)) {
      *psi = an->psi + dpsi;
      *theta = an->theta + dtheta;
      return;
    }
  }
  *psi = std::atan2(v.y(), v.x());
  *theta = std::atan2(-v.z(), h);
}

}  // namespace

const LeaderPath::HelixAnchor& LeaderPath::AnchorOf(double t, HelixAnchor* kept,
                                                    HelixAnchor* local) const {
  const double t0 = std::floor(t);
  HelixAnchor* an = kept != nullptr ? kept : local;
  if (an->t == t0) return *an;
  an->t = t0;
  an->cb = std::cos(kHelixWb * t0);
  an->sb = std::sin(kHelixWb * t0);
  Vec3 p, a;
  HelixPoint(t0, an->cb, an->sb, &p, &an->v, &a);
  an->h = std::sqrt(an->v.x() * an->v.x() + an->v.y() * an->v.y());
  an->h = an->h > 1e-9 ? an->h : 0.0;
  Attitude(an->v, an->h, nullptr, &an->psi, &an->theta);
  return *an;
}

void LeaderPath::Point(double t, HelixAnchor* anchor, Vec3* p, Vec3* v, Vec3* a) const {
  switch (c_.path) {
    case PathKind::kPaperHelix: {
      HelixAnchor local;
      const HelixAnchor& an = AnchorOf(t, anchor, &local);
      // t - an.t is exact for t >= 0 (both within a second of each other); in any case a
      // function of t alone.
      double cb, sb;
      ShiftAngle(kHelixWb * an.t, an.sb, an.cb, kHelixWb * (t - an.t), &sb, &cb);
      HelixPoint(t, cb, sb, p, v, a);
      return;
    }
    case PathKind::kLine:
      *p = c_.start_m + c_.velocity_mps * t;
      *v = c_.velocity_mps;
      *a = Vec3::Zero();
      return;
    case PathKind::kWaypoints: {
      const auto& w = c_.waypoints_m;
      *a = Vec3::Zero();
      if (c_.loop && total_s_ > 0.0) t = std::fmod(t, total_s_);
      if (t >= total_s_) {  // finished: hold at the last waypoint
        *p = w.back();
        *v = Vec3::Zero();
        return;
      }
      std::size_t k = 0;
      while (k + 1 < seg_start_s_.size() && seg_start_s_[k + 1] <= t) ++k;
      const Vec3& from = w[k];
      const Vec3& to = (k + 1 < w.size()) ? w[k + 1] : w.front();
      const Vec3 dir = (to - from).normalized();
      *p = from + dir * c_.speed_mps * (t - seg_start_s_[k]);
      *v = dir * c_.speed_mps;
      return;
    }
  }
}

void LeaderPath::Rates(const Vec3& v, const Vec3& a, double h2, double h, double* theta_dot,
                       double* psi_dot) {
  *psi_dot = (v.x() * a.y() - v.y() * a.x()) / h2;
  const double h_dot = (v.x() * a.x() + v.y() * a.y()) / h;
  *theta_dot = (-h * a.z() + v.z() * h_dot) / (h2 + v.z() * v.z());
}

LeaderSample LeaderPath::At(double t_s, HelixAnchor* anchor) const {
  Vec3 p, v, a;
  HelixAnchor local;
  if (c_.path == PathKind::kPaperHelix && anchor == nullptr) anchor = &local;
  Point(t_s, anchor, &p, &v, &a);
  LeaderSample s;
  const double h2 = v.x() * v.x() + v.y() * v.y();
  const double h = std::sqrt(h2);
  const double speed = std::sqrt(h2 + v.z() * v.z());
  double psi = 0.0, theta = 0.0, psi_dot = 0.0, theta_dot = 0.0;
  if (speed > 1e-9) {
    if (h > 1e-9) {
      Attitude(v, h, c_.path == PathKind::kPaperHelix ? anchor : nullptr, &psi, &theta);
      Rates(v, a, h2, h, &theta_dot, &psi_dot);
    } else {
      theta = std::atan2(-v.z(), h);
    }
  } else if (c_.path == PathKind::kWaypoints && c_.waypoints_m.size() >= 2) {
    // At rest at the end: keep the last segment's attitude.
    const Vec3 d = c_.waypoints_m.back() - c_.waypoints_m[c_.waypoints_m.size() - 2];
    psi = std::atan2(d.y(), d.x());
    theta = std::atan2(-d.z(), std::hypot(d.x(), d.y()));
  }
  s.eta << p, theta, WrapAngle(psi);
  s.eta_dot << v, theta_dot, psi_dot;
  if (speed > 1e-9 && h > 1e-9) {
    // The attitude is the velocity's direction, so its sines and cosines are the
    // velocity's own ratios: no sin and cos of the angles just found.
    s.nu = FossenModel::JInvTimes(AttitudeTrig<double>(h / speed, -v.z() / speed, v.x() / h,
                                                       v.y() / h),
                                  s.eta_dot);
  } else {
    s.nu = FossenModel::JInv(s.eta) * s.eta_dot;
  }
  return s;
}

LeaderPath::FactorSample LeaderPath::FactorAt(double t_s, HelixAnchor* anchor) const {
  Vec3 v, a;
  FactorSample f;
  Point(t_s, anchor, &f.p, &v, &a);
  const double h2 = v.x() * v.x() + v.y() * v.y();
  const double h = std::sqrt(h2);
  const double speed = std::sqrt(h2 + v.z() * v.z());
  double psi_dot = 0.0, theta_dot = 0.0;
  if (speed > 1e-9) {
    if (h > 1e-9) {
      // The heading is the horizontal velocity's direction: its sine is the ratio.
      f.sin_psi = v.y() / h;
      Rates(v, a, h2, h, &theta_dot, &psi_dot);
    }
  } else if (c_.path == PathKind::kWaypoints && c_.waypoints_m.size() >= 2) {
    const Vec3 d = c_.waypoints_m.back() - c_.waypoints_m[c_.waypoints_m.size() - 2];
    const double dh = std::hypot(d.x(), d.y());
    f.sin_psi = dh > 0.0 ? d.y() / dh : 0.0;
  }
  f.eta_dot << v, theta_dot, psi_dot;
  return f;
}

}  // namespace shoal

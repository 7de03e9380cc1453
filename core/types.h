// Shared fixed-size types of the numerical core. SI units throughout.
#pragma once

#include <Eigen/Dense>
#include <cstdint>

namespace shoal {

/// eta = [x y z theta psi] (NED position, pitch, heading) or nu = [u v w q r] (body).
using Vec5 = Eigen::Matrix<double, 5, 1>;
using Mat5 = Eigen::Matrix<double, 5, 5>;
using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

/// Time in the core is an integer count of microseconds (the LCM `utime` unit), so tick
/// arithmetic (delivery at the first tick at or after send + tau) is exact.
using Micros = std::int64_t;

/// The 5-vector (a0, ..., a4), stored pair by pair as Eigen reads a Vec5 back ((a0, a1),
/// (a2, a3), a4). A vector written component by component and soon read whole is read by
/// 16-byte loads that each span two 8-byte stores, which the CPU cannot forward: each such
/// load waits until the stores reach the cache.
inline Vec5 Vec5Of(double a0, double a1, double a2, double a3, double a4) {
  Vec5 v;
  v.head<2>() = Eigen::Vector2d(a0, a1);
  v.segment<2>(2) = Eigen::Vector2d(a2, a3);
  v(4) = a4;
  return v;
}

constexpr double kMicrosPerSecond = 1e6;
inline double ToSeconds(Micros t) { return static_cast<double>(t) / kMicrosPerSecond; }

}  // namespace shoal

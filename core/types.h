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

constexpr double kMicrosPerSecond = 1e6;
inline double ToSeconds(Micros t) { return static_cast<double>(t) / kMicrosPerSecond; }

}  // namespace shoal

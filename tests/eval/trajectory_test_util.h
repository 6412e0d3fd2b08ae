#pragma once
// Trajectories with analytically known ATE, shared by the library and CLI tests.

#include <cmath>
#include <cstddef>
#include <numbers>
#include <vector>

#include <Eigen/Geometry>

#include "hivox/core/pose.h"

namespace hivox::test {

/// Position on a closed 3D loop at angle `theta`. Only harmonics 1 and 2 of theta: sampled at n
/// uniform angles, the sum over every 4th sample (any phase) of each coordinate's varying part
/// is 0 when n / 4 > 2, which is what makes `perturb_zero_mean` invisible to the alignment.
inline Eigen::Vector3d loop_position(double theta) {
  return {1.0 + 2.0 * std::cos(theta), 0.5 + std::sin(theta), 1.2 + 0.5 * std::sin(2.0 * theta)};
}

/// `n` poses on the loop at 30 Hz from `t0_s`, turning about z as they go.
inline std::vector<StampedPose> loop_trajectory(std::size_t n, double t0_s = 1000.0) {
  std::vector<StampedPose> poses(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double theta = 2.0 * std::numbers::pi * static_cast<double>(i) / static_cast<double>(n);
    poses[i].timestamp_s = t0_s + static_cast<double>(i) / 30.0;
    poses[i].T_wc = Pose::Identity();
    poses[i].T_wc.linear() = Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    poses[i].T_wc.translation() = loop_position(theta);
  }
  return poses;
}

/// Position offsets with period 4: +v1, -v1, +v2, -v2. On a `loop_trajectory` whose size is a
/// multiple of 4 and at least 12 they have zero mean and zero cross-covariance with the
/// positions (sum of s_i p_i over each phase pair vanishes), so the optimal rigid alignment of
/// the perturbed trajectory to the loop is the identity and the errors are exactly |v1| for half
/// of the poses and |v2| for the other half.
inline Eigen::Vector3d zero_mean_offset(std::size_t i, const Eigen::Vector3d& v1,
                                        const Eigen::Vector3d& v2) {
  const Eigen::Vector3d& v = (i % 4 < 2) ? v1 : v2;
  return (i % 2 == 0) ? v : Eigen::Vector3d(-v);
}

/// `poses` with `zero_mean_offset` added to the positions, then moved rigidly by `T`.
inline std::vector<StampedPose> perturbed(std::vector<StampedPose> poses, const Eigen::Vector3d& v1,
                                          const Eigen::Vector3d& v2,
                                          const Pose& T = Pose::Identity()) {
  for (std::size_t i = 0; i < poses.size(); ++i) {
    poses[i].T_wc.translation() += zero_mean_offset(i, v1, v2);
    poses[i].T_wc = T * poses[i].T_wc;
  }
  return poses;
}

/// A rigid motion that is far from the identity: 40 degrees about a skew axis, then a shift.
inline Pose some_rigid_motion() {
  Pose T = Pose::Identity();
  T.linear() =
      Eigen::AngleAxisd(40.0 * std::numbers::pi / 180.0, Eigen::Vector3d(1, -2, 0.5).normalized())
          .toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.7, -1.5, 2.0);
  return T;
}

}  // namespace hivox::test

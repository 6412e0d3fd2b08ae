#pragma once
/// @file
/// Rigid poses. The API uses `Eigen::Isometry3d`; `T_wc` is camera-to-world (maps camera-frame
/// points into the world frame). TUM trajectory lines are `t tx ty tz qx qy qz qw`,
/// camera-to-world, with the quaternion's scalar *last* (Eigen's constructor takes it first: use
/// these helpers).

#include <array>
#include <vector>

#include <Eigen/Geometry>

#include "hivox/core/math.h"

namespace hivox {

using Pose = Eigen::Isometry3d;

/// Builds a pose from TUM's order (translation, then qx qy qz qw). The quaternion is normalised;
/// throws `Error(InvalidArgument)` when its norm is not finite or is ~0.
Pose pose_from_tum(double tx, double ty, double tz, double qx, double qy, double qz, double qw);

/// The 7 TUM values `tx ty tz qx qy qz qw` of a pose (qw >= 0).
std::array<double, 7> to_tum(const Pose& pose);

/// Single-precision copy for kernels.
Rigid3f to_rigid3f(const Pose& pose);

/// A pose with its timestamp (seconds).
struct StampedPose {
  double timestamp_s = 0;
  Pose T_wc = Pose::Identity();
};

/// Camera-to-world pose of a camera at `eye_w` looking at `target_w`, with image "up" as close to
/// `up_w` as possible (OpenCV axes: the camera's -y points along up).
Pose look_at(const Eigen::Vector3d& eye_w, const Eigen::Vector3d& target_w,
             const Eigen::Vector3d& up_w);

/// Rotation angle of a relative pose, radians.
double rotation_angle_rad(const Pose& pose);

}  // namespace hivox

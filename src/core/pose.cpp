#include "hivox/core/pose.h"

#include <cmath>

#include "hivox/core/error.h"

namespace hivox {

Pose pose_from_tum(double tx, double ty, double tz, double qx, double qy, double qz, double qw) {
  const Eigen::Quaterniond q(qw, qx, qy, qz);  // Eigen: scalar first
  const double n = q.norm();
  if (!std::isfinite(n) || n < 1e-6)
    fail(ErrorCode::InvalidArgument, "quaternion ({}, {}, {}, {}) has norm {}, not a rotation", qx,
         qy, qz, qw, n);
  if (!std::isfinite(tx) || !std::isfinite(ty) || !std::isfinite(tz))
    fail(ErrorCode::InvalidArgument, "translation ({}, {}, {}) is not finite", tx, ty, tz);
  Pose pose = Pose::Identity();
  pose.linear() = q.normalized().toRotationMatrix();
  pose.translation() = Eigen::Vector3d(tx, ty, tz);
  return pose;
}

std::array<double, 7> to_tum(const Pose& pose) {
  Eigen::Quaterniond q(pose.rotation());
  if (q.w() < 0) q.coeffs() = -q.coeffs();
  const Eigen::Vector3d t = pose.translation();
  return {t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()};
}

Rigid3f to_rigid3f(const Pose& pose) {
  Rigid3f r;
  const Eigen::Matrix3d R = pose.linear();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r.R(i, j) = static_cast<float>(R(i, j));
  const Eigen::Vector3d t = pose.translation();
  r.t = {static_cast<float>(t.x()), static_cast<float>(t.y()), static_cast<float>(t.z())};
  return r;
}

Pose look_at(const Eigen::Vector3d& eye_w, const Eigen::Vector3d& target_w,
             const Eigen::Vector3d& up_w) {
  const Eigen::Vector3d z = (target_w - eye_w).normalized();
  Eigen::Vector3d x = z.cross(up_w);  // camera x (right) = forward x up... with y down
  if (x.norm() < 1e-9) x = z.unitOrthogonal();
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);  // down
  Pose T = Pose::Identity();
  T.linear().col(0) = x;
  T.linear().col(1) = y;
  T.linear().col(2) = z;
  T.translation() = eye_w;
  return T;
}

double rotation_angle_rad(const Pose& pose) {
  return Eigen::AngleAxisd(pose.rotation()).angle();
}

}  // namespace hivox

#pragma once
// The camera, pose and pixel rays the renderers' tests share, computed here independently of
// the renderers.

#include <Eigen/Geometry>

#include "hivox/core/camera.h"
#include "hivox/core/pose.h"

namespace hivox::test {

/// A 160x120 camera with the Kinect-like focal length at that width.
inline PinholeCamera small_camera() {
  return {131.25f, 131.25f, 79.5f, 59.5f, 160, 120};
}

/// A camera 0.3 m off the origin, rotated about two axes: depths vary over the image.
inline Pose oblique_pose() {
  Pose T = Pose::Identity();
  T.linear() = (Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(-0.15, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.1, -0.2, 0.3);
  return T;
}

/// Ray through pixel (u, v) with unit z in the camera frame, pixel centres at integers.
inline Eigen::Vector3d pixel_ray_c(const PinholeCamera& c, int u, int v) {
  return {(u - static_cast<double>(c.cx)) / c.fx, (v - static_cast<double>(c.cy)) / c.fy, 1.0};
}

}  // namespace hivox::test

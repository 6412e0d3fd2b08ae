#include "hivox/core/pose.h"

#include <gtest/gtest.h>

#include <cmath>

#include "hivox/core/error.h"

namespace hivox {
namespace {

TEST(Pose, TumOrderIsScalarLast) {
  // 90 degrees about z: q = (x, y, z, w) = (0, 0, sin 45, cos 45).
  const double s = std::sqrt(0.5);
  const Pose T = pose_from_tum(1, 2, 3, 0, 0, s, s);
  const Eigen::Vector3d x_rotated = T.linear() * Eigen::Vector3d::UnitX();
  EXPECT_NEAR(x_rotated.x(), 0.0, 1e-12);
  EXPECT_NEAR(x_rotated.y(), 1.0, 1e-12);
  EXPECT_NEAR(x_rotated.z(), 0.0, 1e-12);
  EXPECT_EQ(T.translation(), Eigen::Vector3d(1, 2, 3));
}

TEST(Pose, TumRoundTrip) {
  const Pose T = pose_from_tum(1.3357, 0.6698, 1.6180, 0.6504, 0.6012, -0.3056, -0.3496);
  const auto v = to_tum(T);
  const Pose back = pose_from_tum(v[0], v[1], v[2], v[3], v[4], v[5], v[6]);
  EXPECT_TRUE(back.isApprox(T, 1e-12));
  EXPECT_GE(v[6], 0.0);  // canonical sign
  // The input quaternion had qw < 0: the canonical output is its negation (same rotation).
  const double n = std::sqrt(0.6504 * 0.6504 + 0.6012 * 0.6012 + 0.3056 * 0.3056 + 0.3496 * 0.3496);
  EXPECT_NEAR(v[3], -0.6504 / n, 1e-9);
  EXPECT_NEAR(v[6], 0.3496 / n, 1e-9);
}

TEST(Pose, CameraToWorldMapsCameraPointsIntoWorld) {
  // A camera at (0,0,1) looking down -z_w: a point 2 m in front of it is at world z = -1.
  const Pose T_wc = look_at({0, 0, 1}, {0, 0, 0}, {0, 1, 0});
  const Eigen::Vector3d p_w = T_wc * Eigen::Vector3d(0, 0, 2);
  EXPECT_NEAR(p_w.z(), -1.0, 1e-12);
  EXPECT_NEAR(p_w.x(), 0.0, 1e-12);
  EXPECT_NEAR(T_wc.linear().determinant(), 1.0, 1e-12);
}

TEST(Pose, LookAtUsesOpenCvAxes) {
  // Looking along +x with z up: image right is -y_w, image down is -z_w.
  const Pose T_wc = look_at({0, 0, 0}, {1, 0, 0}, {0, 0, 1});
  EXPECT_TRUE(T_wc.linear().col(0).isApprox(Eigen::Vector3d(0, -1, 0)));
  EXPECT_TRUE(T_wc.linear().col(1).isApprox(Eigen::Vector3d(0, 0, -1)));
  EXPECT_TRUE(T_wc.linear().col(2).isApprox(Eigen::Vector3d(1, 0, 0)));
}

TEST(Pose, Rigid3fMatchesEigen) {
  const Pose T = pose_from_tum(0.1, -0.2, 0.3, 0.1, 0.2, 0.3, 0.9);
  const Rigid3f r = to_rigid3f(T);
  const Eigen::Vector3d p(0.5, -1.5, 2.0);
  const Eigen::Vector3d q = T * p;
  const Vec3f qf = r * Vec3f{0.5f, -1.5f, 2.0f};
  EXPECT_NEAR(qf.x, q.x(), 1e-5);
  EXPECT_NEAR(qf.y, q.y(), 1e-5);
  EXPECT_NEAR(qf.z, q.z(), 1e-5);
  const Vec3f back = r.inverse() * qf;
  EXPECT_NEAR(back.x, 0.5f, 1e-5f);
  EXPECT_NEAR(back.y, -1.5f, 1e-5f);
}

TEST(Pose, DegenerateQuaternionIsAnError) {
  EXPECT_THROW(pose_from_tum(0, 0, 0, 0, 0, 0, 0), Error);
  EXPECT_THROW(pose_from_tum(0, 0, std::nan(""), 0, 0, 0, 1), Error);
}

}  // namespace
}  // namespace hivox

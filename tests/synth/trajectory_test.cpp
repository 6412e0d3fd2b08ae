#include "hivox/synth/trajectory.h"

#include <gtest/gtest.h>

#include <cmath>

#include "hivox/core/error.h"
#include "hivox/synth/scene.h"
#include "test_util.h"

namespace hivox {
namespace {

using Vec3 = Eigen::Vector3d;
constexpr double kDeg = M_PI / 180.0;

struct Motion {
  double max_step_m = 0, max_step_rad = 0;    // per frame
  double max_accel_m = 0, max_accel_rad = 0;  // change of the per-frame step
};

Motion motion_of(const std::vector<StampedPose>& poses) {
  Motion m;
  const std::size_t n = poses.size();
  // The path is closed: include the step from the last frame back to the first.
  auto step_t = [&](std::size_t i) {
    return Vec3(poses[(i + 1) % n].T_wc.translation() - poses[i].T_wc.translation());
  };
  auto step_r = [&](std::size_t i) {
    return rotation_angle_rad(poses[i].T_wc.inverse() * poses[(i + 1) % n].T_wc);
  };
  for (std::size_t i = 0; i < n; ++i) {
    m.max_step_m = std::max(m.max_step_m, step_t(i).norm());
    m.max_step_rad = std::max(m.max_step_rad, step_r(i));
    m.max_accel_m = std::max(m.max_accel_m, (step_t((i + 1) % n) - step_t(i)).norm());
    m.max_accel_rad = std::max(m.max_accel_rad, std::abs(step_r((i + 1) % n) - step_r(i)));
  }
  return m;
}

TEST(Trajectory, OfficeArcHasKinectLikeSpeeds) {
  for (const char* name : {"desk", "room"}) {
    const SyntheticScene scene = make_scene(name);
    const auto poses = make_trajectory(scene.camera_path(), 300);
    ASSERT_EQ(poses.size(), 300u);
    EXPECT_DOUBLE_EQ(poses[0].timestamp_s, 0.0);
    EXPECT_NEAR(poses[30].timestamp_s, 1.0, 1e-12);
    const Motion m = motion_of(poses);
    // <= 0.5 m/s and <= 30 deg/s at 30 Hz.
    EXPECT_LE(m.max_step_m, 0.5 / 30) << name;
    EXPECT_LE(m.max_step_rad, 30 * kDeg / 30) << name;
    // Smooth: the per-frame motion changes slowly.
    EXPECT_LE(m.max_accel_m, 0.001) << name;
    EXPECT_LE(m.max_accel_rad, 0.1 * kDeg) << name;
    for (const StampedPose& p : poses) {
      const Vec3 eye = p.T_wc.translation();
      // Eye height and clearance: never inside or too close to anything (Kinect sees >= 0.4 m).
      EXPECT_GT(eye.z(), 1.3);
      EXPECT_LT(eye.z(), 1.6);
      EXPECT_GT(scene.sdf(eye), 0.5) << name;
      // Looks at the table: the optical axis passes within 10 cm of the target.
      const Vec3 axis = p.T_wc.linear().col(2);
      const Vec3 to_target = scene.camera_path().target_w - eye;
      EXPECT_LT((to_target - to_target.dot(axis) * axis).norm(), 0.1);
    }
  }
}

TEST(Trajectory, ClosedObjectsAreSeenFromAllSides) {
  for (const char* name : {"box", "spheres", "keyboard", "blob"}) {
    const SyntheticScene scene = make_scene(name);
    const CameraPath& path = scene.camera_path();
    const auto poses = make_trajectory(path, 360);
    const Motion m = motion_of(poses);
    EXPECT_LE(m.max_step_rad, 2.0 * kDeg) << name;  // one turn plus elevation in 360 frames
    EXPECT_LE(m.max_step_m, 0.02) << name;
    EXPECT_LE(m.max_accel_m, 0.001) << name;
    std::vector<int> azimuth_bins(36, 0);
    double min_elevation = 1, max_elevation = -1;
    for (const StampedPose& p : poses) {
      const Vec3 v = p.T_wc.translation() - path.target_w;
      const double az = std::atan2(v.y(), v.x());
      azimuth_bins[static_cast<int>((az + M_PI) / (2 * M_PI) * 36) % 36]++;
      const double el = std::asin(v.z() / v.norm());
      min_elevation = std::min(min_elevation, el);
      max_elevation = std::max(max_elevation, el);
      EXPECT_GT(v.norm(), 0.5) << name;
      EXPECT_GT(scene.sdf(p.T_wc.translation()), 0.35) << name;
      // The target is on the optical axis.
      const Vec3 axis = p.T_wc.linear().col(2);
      EXPECT_NEAR(axis.dot(-v.normalized()), 1.0, 1e-9);
    }
    for (int b = 0; b < 36; ++b) EXPECT_GT(azimuth_bins[b], 0) << name << " azimuth bin " << b;
    EXPECT_GT(max_elevation, 45 * kDeg) << name << ": sees the top";
    EXPECT_LT(min_elevation, -25 * kDeg) << name << ": sees the bottom";
  }
}

TEST(Trajectory, PathIsClosedAndPeriodic) {
  const CameraPath path = make_scene("desk").camera_path();
  EXPECT_TRUE(camera_pose(path, 0.0).isApprox(camera_pose(path, 1.0), 1e-9));
  EXPECT_TRUE(camera_pose(path, 0.3).isApprox(camera_pose(path, 2.3), 1e-9));
  // Every frame count covers the whole path.
  const auto a = make_trajectory(path, 10);
  const auto b = make_trajectory(path, 20);
  EXPECT_TRUE(a[5].T_wc.isApprox(b[10].T_wc, 1e-12));
}

TEST(Trajectory, ValidationNamesTheField) {
  CameraPath path;
  path.distance_m = 0;
  try {
    path.validate();
    FAIL();
  } catch (const Error& e) {
    EXPECT_TRUE(test::contains(e.what(), "distance_m")) << e.what();
  }
  path = {};
  path.elevation_rad = 1.2;
  path.elevation_swing_rad = 0.5;
  EXPECT_THROW(path.validate(), Error);
  EXPECT_THROW(make_trajectory(CameraPath{}, 10, 0.0), Error);
}

}  // namespace
}  // namespace hivox

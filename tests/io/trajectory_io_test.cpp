#include "hivox/io/trajectory_io.h"

#include <gtest/gtest.h>

#include <cmath>

#include "hivox/core/error.h"
#include "test_util.h"

namespace hivox {
namespace {

using test::error_of;
using test::TempDir;
using test::write_text;

TEST(TumTrajectory, ReadsPosesInFileOrder) {
  TempDir dir;
  write_text(dir / "traj.txt",
             "# comment\n"
             "\n"
             "1.5 1 2 3 0 0 0 1\n"
             "2.5 -1 0.5 4 0 0 0.7071067811865476 0.7071067811865476\n");
  const auto poses = read_tum_trajectory(dir / "traj.txt");
  ASSERT_EQ(poses.size(), 2u);
  EXPECT_EQ(poses[0].timestamp_s, 1.5);
  EXPECT_TRUE(poses[0].T_wc.translation().isApprox(Eigen::Vector3d(1, 2, 3)));
  EXPECT_TRUE(poses[0].T_wc.linear().isIdentity(1e-12));
  // qz = qw = sqrt(1/2): 90 degrees about z, so x maps to y.
  EXPECT_TRUE(
      (poses[1].T_wc.linear() * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY()));
  EXPECT_TRUE(poses[1].T_wc.translation().isApprox(Eigen::Vector3d(-1, 0.5, 4)));
}

TEST(TumTrajectory, MalformedLinesNameFileAndLine) {
  TempDir dir;
  write_text(dir / "short.txt", "# header\n1 0 0 0 0 0 0 1\n\n2 0 0 0 0 0 1\n");
  Error e = error_of([&] { read_tum_trajectory(dir / "short.txt"); });
  EXPECT_EQ(e.code(), ErrorCode::InvalidData);
  EXPECT_TRUE(test::contains(e.what(), "short.txt:4")) << e.what();
  EXPECT_TRUE(test::contains(e.what(), "found 7")) << e.what();

  write_text(dir / "nan.txt", "1 0 0 0 0 0 0 1\n2 0 0 0 zero 0 0 1\n");
  e = error_of([&] { read_tum_trajectory(dir / "nan.txt"); });
  EXPECT_EQ(e.code(), ErrorCode::InvalidData);
  EXPECT_TRUE(test::contains(e.what(), "nan.txt:2")) << e.what();
  EXPECT_TRUE(test::contains(e.what(), "qx")) << e.what();

  write_text(dir / "zero_q.txt", "1 0 0 0 0 0 0 1\n2 0 0 0 0 0 0 1\n3 0 0 0 0 0 0 0\n");
  e = error_of([&] { read_tum_trajectory(dir / "zero_q.txt"); });
  EXPECT_EQ(e.code(), ErrorCode::InvalidData);
  EXPECT_TRUE(test::contains(e.what(), "zero_q.txt:3")) << e.what();

  e = error_of([&] { read_tum_trajectory(dir / "missing.txt"); });
  EXPECT_EQ(e.code(), ErrorCode::Io);
  EXPECT_TRUE(test::contains(e.what(), "missing.txt")) << e.what();
}

TEST(TumTrajectory, FindNearestPose) {
  std::vector<StampedPose> poses(3);
  poses[0].timestamp_s = 10.00;
  poses[1].timestamp_s = 10.10;
  poses[2].timestamp_s = 10.20;
  EXPECT_EQ(find_nearest_pose(poses, 10.105), 1);
  EXPECT_EQ(find_nearest_pose(poses, 10.095), 1);
  EXPECT_EQ(find_nearest_pose(poses, 9.99), 0);   // before the first pose
  EXPECT_EQ(find_nearest_pose(poses, 10.21), 2);  // after the last pose
  EXPECT_EQ(find_nearest_pose(poses, 10.019), 0);
  EXPECT_EQ(find_nearest_pose(poses, 10.05), -1);  // 50 ms from both neighbours
  EXPECT_EQ(find_nearest_pose(poses, 10.23), -1);
  EXPECT_EQ(find_nearest_pose(poses, 9.97), -1);
  EXPECT_EQ(find_nearest_pose(poses, 10.04, 0.06), 0);  // wider window: the nearer one
  EXPECT_EQ(find_nearest_pose(poses, 10.06, 0.06), 1);
  EXPECT_EQ(find_nearest_pose({}, 10.0), -1);
}

TEST(TumTrajectory, WriteReadRoundTrip) {
  TempDir dir;
  std::vector<StampedPose> poses(2);
  poses[0].timestamp_s = 1305031229.528784;
  poses[1].timestamp_s = 1305031229.564442;
  poses[1].T_wc = pose_from_tum(1.3357, 0.6698, 1.6180, 0.6504, 0.6012, -0.3056, -0.3496);
  write_tum_trajectory(dir / "t.txt", poses, "test");
  const auto back = read_tum_trajectory(dir / "t.txt");
  ASSERT_EQ(back.size(), 2u);
  EXPECT_NEAR(back[0].timestamp_s, poses[0].timestamp_s, 1e-6);
  EXPECT_TRUE(back[1].T_wc.isApprox(poses[1].T_wc, 1e-8));
}

}  // namespace
}  // namespace hivox

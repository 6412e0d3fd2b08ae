// Dataset readers on the real sets in ../shared/data (skipped with a message when absent).

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>

#include "dataset_test_util.h"
#include "hivox/core/undistort.h"
#include "hivox/io/dataset.h"
#include "hivox/io/image_io.h"

namespace hivox {
namespace {

using namespace hivox::test;  // NOLINT: test helpers

/// The groundtruth.txt line whose timestamp is nearest to `t_s`, parsed independently of the
/// reader: {t, tx, ty, tz, qx, qy, qz, qw}.
std::vector<double> nearest_groundtruth_line(const std::filesystem::path& file, double t_s) {
  std::ifstream in(file);
  std::vector<double> best;
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    std::vector<double> v(8);
    for (double& x : v) fields >> x;
    if (best.empty() || std::abs(v[0] - t_s) < std::abs(best[0] - t_s)) best = v;
  }
  return best;
}

void expect_pose_equals_line(const Pose& T, const std::vector<double>& v) {
  ASSERT_EQ(v.size(), 8u);
  EXPECT_TRUE(T.translation().isApprox(Eigen::Vector3d(v[1], v[2], v[3]), 1e-9))
      << T.translation().transpose();
  const Eigen::Quaterniond q(T.linear());
  const Eigen::Quaterniond expected = Eigen::Quaterniond(v[7], v[4], v[5], v[6]).normalized();
  EXPECT_NEAR(std::abs(q.dot(expected)), 1.0, 1e-9);  // same rotation (q and -q)
}

TEST(RealData, TumFr1Rpy) {
  HIVOX_REQUIRE_DATASET(dir, "tum_fr1_rpy");
  auto reader = open_dataset(dir.string());
  const DatasetInfo& info = reader->info();
  EXPECT_EQ(info.layout, DatasetLayout::Tum);
  ASSERT_EQ(reader->size(), 694u);
  EXPECT_EQ(info.rig.depth_camera.width, 640);
  EXPECT_EQ(info.rig.depth_camera.height, 480);
  EXPECT_EQ(info.rig.depth_camera.fx, 517.3f);
  EXPECT_EQ(info.rig.depth_scale, 5000.0);
  // First association: rgb 1305031229.528748, depth 1305031229.528784; frames go by depth.
  EXPECT_DOUBLE_EQ(info.first_timestamp_s, 1305031229.528784);
  EXPECT_TRUE(info.has_color);
  // The mocap has a gap around t = 1305031244.88: frames 441-443 lie > 20 ms from any pose.
  EXPECT_EQ(info.ground_truth_count, 691u);
  EXPECT_NEAR(info.median_frame_step_s, 1.0 / 30.0, 0.002);
  EXPECT_TRUE(info.warnings.empty());

  const RgbdFrame f = reader->read(100);
  EXPECT_DOUBLE_EQ(f.timestamp_s, 1305031232.868557);
  ASSERT_TRUE(f.T_wc_gt.has_value());
  expect_pose_equals_line(*f.T_wc_gt,
                          nearest_groundtruth_line(dir / "groundtruth.txt", f.timestamp_s));
  EXPECT_EQ(f.color.width(), 640);
  // Depth is the raw PNG over 5000, with the fr1 lens distortion of intrinsics.json removed:
  // as read with --keep-distortion, then resampled.
  EXPECT_TRUE(info.undistorted);
  EXPECT_EQ(info.distortion.k1, 0.2624f);
  const Image<uint16_t> raw = read_depth16(dir / "depth/1305031232.868557.png");
  DatasetParams keep;
  keep.undistort = false;
  const RgbdFrame kept = open_dataset(dir.string(), keep)->read(100);
  for (const auto& [x, y] : {std::pair{320, 240}, std::pair{100, 400}, std::pair{600, 50}})
    EXPECT_FLOAT_EQ(kept.depth_m(x, y), raw(x, y) / 5000.0f) << x << "," << y;
  const DepthImage undistorted =
      Undistorter(info.rig.depth_camera, info.distortion).depth(kept.depth_m);
  for (std::size_t i = 0; i < undistorted.size(); ++i)
    ASSERT_EQ(f.depth_m.data()[i], undistorted.data()[i]) << i;
  for (std::size_t i : {441u, 442u, 443u}) EXPECT_FALSE(reader->read(i).T_wc_gt.has_value()) << i;
  EXPECT_TRUE(reader->read(444).T_wc_gt.has_value());
}

TEST(RealData, TumFr1RpyFromRgbAndDepthLists) {
  // The same folder without associations.txt: rgb.txt + depth.txt associated by the TUM rule
  // give exactly the 694 pairs of the shipped associations.txt.
  HIVOX_REQUIRE_DATASET(dir, "tum_fr1_rpy");
  TempDir copy;
  for (const char* name : {"rgb.txt", "depth.txt", "groundtruth.txt", "intrinsics.json"})
    std::filesystem::create_symlink(dir / name, copy / name);
  for (const char* name : {"rgb", "depth"})
    std::filesystem::create_directory_symlink(dir / name, copy / name);
  auto from_lists = open_dataset(copy.path().string());
  auto from_associations = open_dataset(dir.string());
  ASSERT_EQ(from_lists->size(), from_associations->size());
  EXPECT_EQ(from_lists->info().ground_truth_count, 691u);
  std::ifstream in(dir / "associations.txt");
  std::vector<double> depth_times;
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    double t_rgb = 0, t_depth = 0;
    std::string rgb_file;
    fields >> t_rgb >> rgb_file >> t_depth;
    depth_times.push_back(t_depth);
  }
  ASSERT_EQ(depth_times.size(), 694u);
  // Timestamps only (cheap); one decoded frame checks the files.
  const RgbdFrame a = from_lists->read(500), b = from_associations->read(500);
  EXPECT_DOUBLE_EQ(a.timestamp_s, depth_times[500]);
  EXPECT_DOUBLE_EQ(a.timestamp_s, b.timestamp_s);
  for (std::size_t i = 0; i < a.depth_m.size(); i += 997)
    ASSERT_EQ(a.depth_m.data()[i], b.depth_m.data()[i]);
  EXPECT_EQ(a.color(10, 10), b.color(10, 10));
}

TEST(RealData, TumFr3CabinetKeyframes) {
  HIVOX_REQUIRE_DATASET(dir, "tum_fr3_cabinet_keyframes");
  auto reader = open_dataset(dir.string());
  const DatasetInfo& info = reader->info();
  ASSERT_EQ(reader->size(), 58u);
  EXPECT_EQ(info.rig.depth_camera.width, 640);
  EXPECT_EQ(info.rig.depth_camera.fx, 535.4f);
  EXPECT_DOUBLE_EQ(info.first_timestamp_s, 1341841278.8427);
  EXPECT_EQ(info.ground_truth_count, 58u);
  // Keyframes ~0.67 s apart: too far apart for tracking, and said so.
  EXPECT_NEAR(info.median_frame_step_s, 0.67, 0.01);
  ASSERT_EQ(info.warnings.size(), 1u);
  EXPECT_TRUE(test::contains(info.warnings[0], "frames are 0.67 s apart")) << info.warnings[0];
  const RgbdFrame f = reader->read(2);
  EXPECT_DOUBLE_EQ(f.timestamp_s, 1341841280.1825);
  ASSERT_TRUE(f.T_wc_gt.has_value());
  expect_pose_equals_line(
      *f.T_wc_gt, {1341841280.1825, -2.3319, 1.1799, 1.1107, -0.4077, 0.8121, -0.3749, 0.1837});
}

TEST(RealData, ReplicaOffice0) {
  HIVOX_REQUIRE_DATASET(dir, "replica_office0");
  auto reader = open_dataset(dir.string());
  const DatasetInfo& info = reader->info();
  ASSERT_EQ(reader->size(), 4u);
  EXPECT_EQ(info.rig.depth_camera.width, 1200);
  EXPECT_EQ(info.rig.depth_camera.height, 680);
  EXPECT_EQ(info.rig.depth_scale, 6553.5);
  EXPECT_EQ(info.ground_truth_count, 4u);
  EXPECT_TRUE(info.warnings.empty());
  const RgbdFrame f = reader->read(3);
  EXPECT_DOUBLE_EQ(f.timestamp_s, 0.1);
  ASSERT_TRUE(f.T_wc_gt.has_value());
  expect_pose_equals_line(*f.T_wc_gt, nearest_groundtruth_line(dir / "groundtruth.txt", 0.1));
  EXPECT_EQ(f.color.width(), 1200);
  const Image<uint16_t> raw = read_depth16(dir / "depth/0.100000.png");
  EXPECT_FLOAT_EQ(f.depth_m(600, 340), static_cast<float>(raw(600, 340) / 6553.5));
}

TEST(RealData, ThreeDMatchSun3dSample) {
  HIVOX_REQUIRE_DATASET(dir, "3dmatch_sun3d_sample");
  auto reader = open_dataset(dir.string());
  const DatasetInfo& info = reader->info();
  ASSERT_EQ(reader->size(), 5u);
  EXPECT_EQ(info.rig.depth_camera.width, 640);
  EXPECT_EQ(info.rig.depth_scale, 1000.0);
  EXPECT_EQ(info.ground_truth_count, 5u);
  // Frames 0, 1, 2, 116 and 422 of a 30 frames/s sequence: the median step is 3.8 s.
  ASSERT_EQ(info.warnings.size(), 1u);
  EXPECT_TRUE(test::contains(info.warnings[0], "frames are 3.80 s apart")) << info.warnings[0];
  const RgbdFrame f = reader->read(4);
  ASSERT_TRUE(f.T_wc_gt.has_value());
  expect_pose_equals_line(*f.T_wc_gt,
                          nearest_groundtruth_line(dir / "groundtruth.txt", f.timestamp_s));
}

TEST(RealData, ThreeDMatchAsSevenScenesLayout) {
  // The 3DMatch sample kept its original 7-Scenes-style pose files (orig/frame-NNNNNN.pose.txt):
  // rebuilt as a 7-Scenes sequence, the 7-Scenes reader must give the TUM reader's poses.
  HIVOX_REQUIRE_DATASET(dir, "3dmatch_sun3d_sample");
  TempDir scene;
  const auto seq = scene / "seq-01";
  std::filesystem::create_directories(seq);
  const char* tum_names[] = {"0.000000", "0.033333", "0.066667", "3.866667", "14.066667"};
  const int numbers[] = {0, 1, 2, 116, 422};
  for (int i = 0; i < 5; ++i) {
    const std::string stem = fmt::format("frame-{:06d}", numbers[i]);
    std::filesystem::copy_file(dir / "orig" / (stem + ".pose.txt"), seq / (stem + ".pose.txt"));
    std::filesystem::create_symlink(dir / "depth" / (std::string(tum_names[i]) + ".png"),
                                    seq / (stem + ".depth.png"));
    std::filesystem::create_symlink(dir / "rgb" / (std::string(tum_names[i]) + ".png"),
                                    seq / (stem + ".color.png"));
  }
  write_intrinsics(scene / "intrinsics.json", {570.342205f, 570.342205f, 320, 240, 640, 480}, 0);
  auto seven = open_dataset(scene.path().string());
  auto tum = open_dataset(dir.string());
  EXPECT_EQ(seven->info().layout, DatasetLayout::SevenScenes);
  ASSERT_EQ(seven->size(), 5u);
  EXPECT_EQ(seven->info().rig.depth_scale, 1000.0);  // the 7-Scenes default: millimetres
  for (std::size_t i = 0; i < 5; ++i) {
    const RgbdFrame a = seven->read(i), b = tum->read(i);
    ASSERT_TRUE(a.T_wc_gt && b.T_wc_gt);
    EXPECT_TRUE(a.T_wc_gt->translation().isApprox(b.T_wc_gt->translation(), 1e-6)) << i;
    EXPECT_TRUE(a.T_wc_gt->linear().isApprox(b.T_wc_gt->linear(), 1e-5)) << i;
    EXPECT_EQ(a.depth_m(320, 240), b.depth_m(320, 240)) << i;
  }
}

}  // namespace
}  // namespace hivox

#include "hivox/synth_mesh/mesh_dataset.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "hivox/core/error.h"
#include "synth/mesh_shapes.h"
#include "test_util.h"

namespace hivox {
namespace {

using Vec3 = Eigen::Vector3d;
using test::small_camera;

MeshScene unit_cube() {
  return MeshScene(test::box_mesh(Vec3(0, 0, 0.5), Vec3(0.5, 0.5, 0.5)));
}

// Ten poses circling the cube, 0.1 s apart.
std::vector<StampedPose> circle(std::size_t n = 10) {
  std::vector<StampedPose> poses;
  for (std::size_t i = 0; i < n; ++i) {
    const double a = 0.3 * static_cast<double>(i);
    poses.push_back(
        {1.0 + 0.1 * static_cast<double>(i),
         look_at(Vec3(3 * std::cos(a), 3 * std::sin(a), 1.2), Vec3(0, 0, 0.5), Vec3::UnitZ())});
  }
  return poses;
}

MeshSequenceParams clean_params() {
  MeshSequenceParams p;
  p.camera = small_camera();
  p.noise = NoiseParams::none();
  return p;
}

TEST(MeshDataset, FramesAreTheChosenPosesExactly) {
  const std::vector<StampedPose> poses = circle();
  MeshSequenceParams params = clean_params();
  params.stride = 3;
  MeshDataset all(unit_cube(), poses, params, "cube");
  ASSERT_EQ(all.size(), 4u);  // poses 0, 3, 6, 9
  params.max_frames = 3;
  MeshDataset data(unit_cube(), poses, params, "cube");
  ASSERT_EQ(data.size(), 3u);
  EXPECT_EQ(data.info().source, "cube");
  EXPECT_EQ(data.info().layout, DatasetLayout::Synthetic);
  EXPECT_TRUE(data.info().has_color);
  EXPECT_TRUE(data.info().has_ground_truth);
  EXPECT_EQ(data.info().rig.depth_camera, small_camera());
  EXPECT_DOUBLE_EQ(data.info().first_timestamp_s, 1.0);
  for (std::size_t i = 0; i < data.size(); ++i) {
    const RgbdFrame f = data.read(i);
    const StampedPose& want = poses[3 * i];
    EXPECT_EQ(f.index, i);
    EXPECT_EQ(f.timestamp_s, want.timestamp_s);
    ASSERT_TRUE(f.T_wc_gt);
    EXPECT_EQ(f.T_wc_gt->matrix(), want.T_wc.matrix());  // exact: no round trip
    // Without noise the depth is the clean render at that pose.
    const RenderedFrame clean = render(data.scene(), small_camera(), want.T_wc, 10.0);
    ASSERT_EQ(f.depth_m.width(), 160);
    std::size_t valid = 0;
    for (std::size_t k = 0; k < f.depth_m.size(); ++k) {
      ASSERT_EQ(f.depth_m.data()[k], clean.depth_m.data()[k]);
      valid += f.depth_m.data()[k] > 0;
    }
    EXPECT_GT(valid, 1000u);
  }
  EXPECT_THROW(data.read(3), Error);
}

TEST(MeshDataset, NoiseChangesDepthButNotPoses) {
  MeshSequenceParams params = clean_params();
  params.noise = NoiseParams::kinect();
  MeshDataset data(unit_cube(), circle(2), params);
  const RgbdFrame f = data.read(1);
  const RenderedFrame clean = data.render_clean(1);
  std::size_t changed = 0;
  for (std::size_t k = 0; k < f.depth_m.size(); ++k)
    changed += f.depth_m.data()[k] != clean.depth_m.data()[k];
  EXPECT_GT(changed, 1000u);
  EXPECT_EQ(f.T_wc_gt->matrix(), circle(2)[1].T_wc.matrix());
}

TEST(MeshDataset, BadTrajectoriesAndParamsAreClearErrors) {
  Error e = test::error_of([] { MeshDataset d(unit_cube(), {}, clean_params()); });
  EXPECT_TRUE(test::contains(e.what(), "no poses")) << e.what();

  std::vector<StampedPose> back = circle(4);
  back[1].timestamp_s = back[0].timestamp_s + 4e-7;  // the same microsecond: the same file name
  e = test::error_of([&] { MeshDataset d(unit_cube(), back, clean_params()); });
  EXPECT_TRUE(test::contains(e.what(), "pose 1")) << e.what();

  MeshSequenceParams p = clean_params();
  p.stride = 2;  // pose 1 is skipped: the same trajectory is fine
  EXPECT_NO_THROW(MeshDataset(unit_cube(), back, p));

  p = clean_params();
  p.stride = 0;
  e = test::error_of([&] { MeshDataset d(unit_cube(), circle(), p); });
  EXPECT_TRUE(test::contains(e.what(), "stride")) << e.what();

  p = clean_params();
  p.camera.fx = 0;
  EXPECT_THROW(MeshDataset(unit_cube(), circle(), p), Error);

  std::vector<StampedPose> nan = circle(3);
  nan[1].T_wc.translation().x() = std::nan("");
  e = test::error_of([&] { MeshDataset d(unit_cube(), nan, clean_params()); });
  EXPECT_TRUE(test::contains(e.what(), "pose 1")) << e.what();
}

// The orbit framing a box keeps it whole in view on every frame, fills a good part of the image
// and looks at it from all sides; `make_trajectory_up` turns the path so the camera's image up
// follows the given axis.
TEST(MeshDataset, FramingOrbitKeepsTheObjectInView) {
  const Vec3 center(1.0, -2.0, 0.3), half(0.4, 0.25, 0.15);
  const MeshScene scene(test::box_mesh(center, half));
  const PinholeCamera cam = small_camera();
  const CameraPath path = framing_orbit(scene.bounds(), cam);
  EXPECT_TRUE(path.target_w.isApprox(center, 1e-6));
  for (const Vec3& up : {Vec3(0, 0, 1), Vec3(0, 1, 0), Vec3(-1, 0, 0)}) {
    const std::vector<StampedPose> poses = make_trajectory_up(path, 24, up);
    ASSERT_EQ(poses.size(), 24u);
    for (const StampedPose& p : poses) {
      const Vec3 forward = p.T_wc.linear().col(2);
      const Vec3 image_up = -p.T_wc.linear().col(1);  // OpenCV: y down
      EXPECT_GT(forward.dot((center - p.T_wc.translation()).normalized()), 0.9999);
      EXPECT_GT(image_up.dot(up), 0.0);
      const RenderedFrame f = render(scene, cam, p.T_wc, 100.0);
      std::size_t valid = 0;
      for (std::size_t k = 0; k < f.depth_m.size(); ++k) valid += f.depth_m.data()[k] > 0;
      EXPECT_GT(valid, f.depth_m.size() / 20);
      for (int u = 0; u < cam.width; ++u)
        ASSERT_EQ(f.depth_m(u, 0) + f.depth_m(u, cam.height - 1), 0.0f) << "cut at the border";
      for (int v = 0; v < cam.height; ++v)
        ASSERT_EQ(f.depth_m(0, v) + f.depth_m(cam.width - 1, v), 0.0f) << "cut at the border";
    }
  }
  EXPECT_THROW(framing_orbit(Aabb{}, cam), Error);
  EXPECT_THROW(make_trajectory_up(path, 3, Vec3::Zero()), Error);
}

}  // namespace
}  // namespace hivox

// The mesh renderer against real renders: Replica office0's depth images (rendered from the full
// mesh by another renderer) and hivox's render of the decimated mesh at the same poses.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "hivox/io/image_io.h"
#include "hivox/io/intrinsics_io.h"
#include "hivox/io/mesh_file.h"
#include "hivox/io/trajectory_io.h"
#include "hivox/synth_mesh/mesh_render.h"
#include "test_util.h"

namespace hivox {
namespace {

double quantile(std::vector<double> v, double q) {
  const auto k = static_cast<std::size_t>(q * static_cast<double>(v.size() - 1));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

TEST(MeshRenderReal, ReplicaDepthMatchesTheRealRenders) {
  HIVOX_REQUIRE_DATASET(dir, "replica_office0");
  const IntrinsicsFile intr = read_intrinsics_json(dir / "intrinsics.json");
  const std::vector<StampedPose> poses = read_tum_trajectory(dir / "groundtruth.txt");
  const MeshScene scene(read_mesh(dir / "office0_mesh_decimated50k.ply"));
  ASSERT_GE(poses.size(), 4u);
  for (int i = 0; i < 4; ++i) {
    const std::string name = fmt::format("{:.6f}.png", poses[i].timestamp_s);
    const DepthImage real = depth_to_metres(read_depth16(dir / "depth" / name), intr.depth_scale);
    const RenderedFrame ours = render(scene, intr.camera, poses[i].T_wc, 10.0);
    ASSERT_EQ(real.width(), ours.depth_m.width());
    ASSERT_EQ(real.height(), ours.depth_m.height());
    std::vector<double> diff;
    std::size_t only_one = 0;
    for (std::size_t k = 0; k < real.size(); ++k) {
      const float a = real.data()[k], b = ours.depth_m.data()[k];
      if (a > 0 && b > 0)
        diff.push_back(std::abs(a - b));
      else if ((a > 0) != (b > 0))
        ++only_one;
    }
    ASSERT_GT(diff.size(), real.size() * 9 / 10) << name;
    const double median = quantile(diff, 0.5), p90 = quantile(diff, 0.9);
    const auto far = std::count_if(diff.begin(), diff.end(), [](double d) { return d > 0.05; });
    std::printf(
        "replica_office0 %s: %zu pixels valid in both, median |dz| %.2f mm, 90%% %.2f mm, "
        "%.2f%% beyond 5 cm, %zu valid in one only\n",
        name.c_str(), diff.size(), 1e3 * median, 1e3 * p90,
        100.0 * static_cast<double>(far) / static_cast<double>(diff.size()), only_one);
    // The decimated mesh lies within a few millimetres of the full one.
    EXPECT_LT(median, 0.003) << name;
    EXPECT_LT(static_cast<double>(far), 0.02 * static_cast<double>(diff.size())) << name;
  }
}

}  // namespace
}  // namespace hivox

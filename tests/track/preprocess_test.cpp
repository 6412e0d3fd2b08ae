// Depth preprocessing for tracking on images whose geometry is known exactly: planes (normals,
// points), a depth step (the bilateral filter must not blur across it), range limits and the
// pyramid.

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <utility>

#include <Eigen/Core>

#include "hivox/track/preprocess.h"
#include "track/track_kernels.h"

namespace hivox {
namespace {

PinholeCamera camera() {
  PinholeCamera c;
  c.fx = c.fy = 300.0;
  c.cx = 79.5;
  c.cy = 59.5;
  c.width = 160;
  c.height = 120;
  return c;
}

// Depth of the plane n . p = d (camera frame) along each pixel's ray.
DepthImage plane_depth(const PinholeCamera& c, const Eigen::Vector3d& n, double d) {
  DepthImage depth(c.width, c.height, 0.0f);
  for (int y = 0; y < c.height; ++y)
    for (int x = 0; x < c.width; ++x) {
      const Eigen::Vector3d ray((x - c.cx) / c.fx, (y - c.cy) / c.fy, 1.0);
      depth(x, y) = static_cast<float>(d / n.dot(ray));
    }
  return depth;
}

TEST(Preprocess, NormalsAndPointsOfATiltedPlane) {
  const PinholeCamera c = camera();
  const Eigen::Vector3d n = Eigen::Vector3d(0.3, -0.2, -1.0).normalized();  // faces the camera
  const DepthImage depth = plane_depth(c, n, -1.2 * std::abs(n.z()));
  TrackParams params;
  Image<Vec3f> points, normals;
  points_and_normals(depth, c, params, points, normals);
  int checked = 0;
  for (int y = 1; y + 1 < c.height; ++y)
    for (int x = 1; x + 1 < c.width; ++x) {
      const Vec3f& nn = normals(x, y);
      ASSERT_NEAR(norm(nn), 1.0f, 1e-4f) << x << "," << y;
      EXPECT_NEAR(nn.x, n.x(), 2e-3) << x << "," << y;
      EXPECT_NEAR(nn.y, n.y(), 2e-3);
      EXPECT_NEAR(nn.z, n.z(), 2e-3);
      const Vec3f& p = points(x, y);
      EXPECT_NEAR(p.z, depth(x, y), 1e-6f);
      EXPECT_NEAR(p.x, (x - c.cx) / c.fx * depth(x, y), 1e-5);
      ++checked;
    }
  EXPECT_EQ(checked, (c.width - 2) * (c.height - 2));
  EXPECT_EQ(norm(normals(0, 10)), 0.0f) << "border pixels get no normal";
}

TEST(Preprocess, NoNormalAcrossADepthStep) {
  const PinholeCamera c = camera();
  DepthImage depth(c.width, c.height, 1.0f);
  for (int y = 0; y < c.height; ++y)
    for (int x = 80; x < c.width; ++x) depth(x, y) = 1.5f;
  TrackParams params;
  Image<Vec3f> points, normals;
  points_and_normals(depth, c, params, points, normals);
  for (int y = 1; y + 1 < c.height; ++y) {
    EXPECT_EQ(norm(normals(79, y)), 0.0f);
    EXPECT_EQ(norm(normals(80, y)), 0.0f);
    EXPECT_NEAR(normals(78, y).z, -1.0f, 1e-5f);
    EXPECT_NEAR(normals(81, y).z, -1.0f, 1e-5f);
  }
}

TEST(Preprocess, BilateralSmoothsNoiseButKeepsEdges) {
  const PinholeCamera c = camera();
  DepthImage clean(c.width, c.height, 1.0f);
  for (int y = 0; y < c.height; ++y)
    for (int x = 80; x < c.width; ++x) clean(x, y) = 1.5f;
  DepthImage noisy = clean;
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 0.003f);
  for (int y = 0; y < c.height; ++y)
    for (int x = 0; x < c.width; ++x) noisy(x, y) += noise(rng);
  noisy(40, 40) = 0.0f;  // a hole stays a hole
  TrackParams params;
  DepthImage filtered;
  bilateral_filter(noisy, filtered, params, DepthRange{});
  double before = 0, after = 0;
  int n = 0;
  for (int y = 3; y + 3 < c.height; ++y)
    for (int x = 3; x + 3 < c.width; ++x) {
      if (x == 40 && y == 40) continue;
      before += std::pow(noisy(x, y) - clean(x, y), 2);
      after += std::pow(filtered(x, y) - clean(x, y), 2);
      ++n;
    }
  EXPECT_LT(std::sqrt(after / n), 0.5 * std::sqrt(before / n)) << "noise is reduced";
  for (int y = 3; y + 3 < c.height; ++y) {  // pixels beside the 0.5 m step keep their side
    EXPECT_NEAR(filtered(79, y), 1.0f, 0.006f);
    EXPECT_NEAR(filtered(80, y), 1.5f, 0.006f);
  }
  EXPECT_EQ(filtered(40, 40), 0.0f);
}

TEST(Preprocess, RowWiseFilterEqualsThePerPixelKernel) {
  // The CPU filter sums over whole rows at once; it must give what the per-pixel kernel (the one
  // a GPU driver runs) gives, at borders, holes and out-of-range depths included.
  const PinholeCamera c = camera();
  DepthImage depth(c.width, c.height);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int y = 0; y < c.height; ++y)
    for (int x = 0; x < c.width; ++x) {
      const float r = u(rng);
      depth(x, y) = r < 0.1f ? 0.0f : (r < 0.12f ? 3.5f : 1.0f + 0.01f * x + 0.05f * u(rng));
    }
  TrackParams params;
  for (int radius : {1, 2, 4}) {
    params.bilateral_radius_px = radius;
    DepthImage filtered;
    const DepthRange range;
    bilateral_filter(depth, filtered, params, range);
    const float inv_px = 1.0f / (2.0f * params.bilateral_sigma_px * params.bilateral_sigma_px);
    const float inv_d =
        1.0f / (2.0f * params.bilateral_sigma_depth_m * params.bilateral_sigma_depth_m);
    int differ = 0;
    for (int y = 0; y < c.height; ++y)
      for (int x = 0; x < c.width; ++x) {
        const float expect = kernels::bilateral_depth(std::as_const(depth).view(), x, y, radius,
                                                      inv_px, inv_d, range.min_m, range.max_m);
        differ += std::abs(filtered(x, y) - expect) > 1e-5f;
      }
    EXPECT_EQ(differ, 0) << "radius " << radius;
  }
}

TEST(Preprocess, DepthRangeAndPyramid) {
  const PinholeCamera c = camera();
  DepthImage depth(c.width, c.height, 2.0f);
  depth(10, 10) = 0.1f;  // nearer than min_depth_m
  depth(20, 20) = 5.0f;  // farther than max_depth_m
  TrackParams params;
  const DepthRange range{0.2f, 3.0f};
  DepthImage filtered;
  bilateral_filter(depth, filtered, params, range);
  EXPECT_EQ(filtered(10, 10), 0.0f);
  EXPECT_EQ(filtered(20, 20), 0.0f);
  EXPECT_FLOAT_EQ(filtered(30, 30), 2.0f);

  std::vector<PyramidLevel> levels;
  build_pyramid(depth, c, params, range, levels);
  ASSERT_EQ(static_cast<int>(levels.size()), params.levels());
  for (std::size_t i = 1; i < levels.size(); ++i) {
    const PyramidLevel& l = levels[i];
    EXPECT_EQ(l.depth_m.width(), levels[i - 1].depth_m.width() / 2);
    EXPECT_EQ(l.camera.width, l.depth_m.width());
    EXPECT_NEAR(l.camera.fx, levels[i - 1].camera.fx / 2, 1e-9);
    // The same 3D point: pixel centre (x, y) at level i is (2x + 0.5, 2y + 0.5) one level up.
    EXPECT_NEAR((l.camera.cx + 0.5) * 2 - 0.5, levels[i - 1].camera.cx, 1e-9);
    EXPECT_FLOAT_EQ(l.depth_m(l.depth_m.width() / 2, l.depth_m.height() / 2), 2.0f);
  }
}

}  // namespace
}  // namespace hivox

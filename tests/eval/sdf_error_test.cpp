// sdf-error (paper Table I) where the answer is known: maps written from exact signed distance
// functions at a fine and a coarse voxel size. A plane's SDF is linear, so trilinear
// interpolation reproduces it at any resolution: the coarse map's error at the fine mesh is ~0.
// A sphere's SDF curves: trilinear interpolation at voxel size h errs by at most h^2 / (4 R)
// (half the sum of the second derivatives' bounds, 2 / R, times h^2 / 8), which bounds the score.

#include "hivox/eval/sdf_error.h"

#include <gtest/gtest.h>

#include <cmath>

#include "hivox/core/error.h"
#include "hivox/mesh/extract_mesh.h"
#include "mesh/mesh_test_util.h"

namespace hivox {
namespace {

constexpr double kMu = 0.024;

/// A single-level map of voxel size `voxel_m` holding `sdf` exactly in the blocks over the box
/// [-half, half]^3 (metres).
std::unique_ptr<VoxelBlockMap> exact_map(float voxel_m, double half_m, const test::Sdf& sdf) {
  auto map = std::make_unique<VoxelBlockMap>(
      test::mesh_map_params(voxel_m, 1, false, static_cast<float>(kMu)));
  const double block_m = 8.0 * voxel_m;
  const int lo = static_cast<int>(std::floor(-half_m / block_m));
  const int hi = static_cast<int>(std::floor(half_m / block_m));
  test::write_sdf_blocks(*map, 0, {lo, lo, lo}, {hi, hi, hi}, kMu, sdf);
  return map;
}

SdfErrorParams sdf_samples(int64_t samples = 20000) {
  SdfErrorParams p;
  p.samples = samples;
  return p;
}

TEST(SdfError, APlaneScoresZeroAtEveryResolution) {
  const double z0 = 0.0123;  // off the voxel grid of both maps
  const test::Sdf plane = [&](const Eigen::Vector3d& p) { return p.z() - z0; };
  const auto fine = exact_map(0.002f, 0.1, plane);
  const auto coarse = exact_map(0.008f, 0.14, plane);
  const TriangleMesh mesh = extract_mesh(*fine);
  ASSERT_GT(mesh.triangle_count(), 100);
  const NamedMap maps[] = {{"fine", fine.get()}, {"coarse", coarse.get()}};
  const SdfErrorResult r = evaluate_sdf_error(mesh, maps, sdf_samples());
  ASSERT_EQ(r.samples, 20000);
  ASSERT_EQ(r.maps.size(), 2u);
  EXPECT_EQ(r.maps[0].name, "fine");
  EXPECT_EQ(r.maps[1].name, "coarse");
  for (const MapSdfError& m : r.maps) {
    EXPECT_EQ(m.found, r.samples) << m.name;  // the coarse box holds the fine one
    EXPECT_DOUBLE_EQ(m.coverage, 1.0);
    EXPECT_LT(m.mean_abs_sdf_m, 5e-6) << m.name;  // TSDF quantisation only (mu / 32767)
    EXPECT_LE(m.median_abs_sdf_m, m.rmse_m + 1e-12);
    ASSERT_EQ(m.points_per_level.size(), 1u);
    EXPECT_EQ(m.points_per_level[0], r.samples);
  }
  // The points lie on the plane.
  for (std::size_t i = 0; i < r.points_w.size(); i += 97) EXPECT_NEAR(r.points_w[i].z, z0, 1e-5);
  ASSERT_EQ(r.per_point_m.size(), 2u);
  EXPECT_EQ(r.per_point_m[1].size(), r.points_w.size());
}

TEST(SdfError, ASphereIsBoundedByTheCurvatureTerm) {
  const double radius = 0.08;
  const Eigen::Vector3d centre(0.0031, -0.0017, 0.0057);
  const test::Sdf sphere = [&](const Eigen::Vector3d& p) { return (p - centre).norm() - radius; };
  const double fine_m = 0.002, coarse_m = 0.008;
  const auto fine = exact_map(static_cast<float>(fine_m), 0.11, sphere);
  const auto coarse = exact_map(static_cast<float>(coarse_m), 0.13, sphere);
  const TriangleMesh mesh = extract_mesh(*fine);
  const NamedMap maps[] = {{"fine", fine.get()}, {"coarse", coarse.get()}};
  const SdfErrorResult r = evaluate_sdf_error(mesh, maps, sdf_samples());
  const double fine_bound = fine_m * fine_m / (4 * radius);
  const double bound = (coarse_m * coarse_m + fine_m * fine_m) / (4 * radius);
  EXPECT_EQ(r.maps[1].found, r.samples);
  EXPECT_LT(r.maps[0].mean_abs_sdf_m, fine_bound);
  EXPECT_LT(r.maps[1].mean_abs_sdf_m, bound);
  // The coarse grid's curvature error is visible: well above the fine grid's and above a tenth
  // of its bound (so the test would notice a score stuck at 0).
  EXPECT_GT(r.maps[1].mean_abs_sdf_m, 4 * r.maps[0].mean_abs_sdf_m);
  EXPECT_GT(r.maps[1].mean_abs_sdf_m, 0.1 * bound);
  // Every point's own error respects the bound (the maximum of the interpolation error).
  for (float e : r.per_point_m[1]) ASSERT_LT(e, bound);
}

TEST(SdfError, PointsOutsideAMapAreNotFound) {
  const test::Sdf plane = [](const Eigen::Vector3d& p) { return p.z(); };
  const auto fine = exact_map(0.002f, 0.1, plane);
  // A coarse map holding only the half x < 0 of the plane.
  auto half = std::make_unique<VoxelBlockMap>(
      test::mesh_map_params(0.008f, 1, false, static_cast<float>(kMu)));
  test::write_sdf_blocks(*half, 0, {-3, -3, -3}, {-1, 2, 2}, kMu, plane);
  const TriangleMesh mesh = extract_mesh(*fine);
  const NamedMap maps[] = {{"half", half.get()}};
  const SdfErrorResult r = evaluate_sdf_error(mesh, maps, sdf_samples());
  // Points with x < 0 are found except within one coarse voxel of the border, where the
  // interpolation would need the missing block's voxels.
  EXPECT_GT(r.maps[0].coverage, 0.42);
  EXPECT_LT(r.maps[0].coverage, 0.5);
  for (std::size_t i = 0; i < r.points_w.size(); ++i) {
    if (r.points_w[i].x > 0.0f) {
      ASSERT_LT(r.per_point_m[0][i], 0.0f);
    } else if (r.points_w[i].x < -0.0081f) {
      ASSERT_GE(r.per_point_m[0][i], 0.0f);
    }
  }
}

TEST(SdfError, RefusesBadInput) {
  const test::Sdf plane = [](const Eigen::Vector3d& p) { return p.z(); };
  const auto fine = exact_map(0.002f, 0.05, plane);
  const TriangleMesh mesh = extract_mesh(*fine);
  const NamedMap null_map[] = {{"x", nullptr}};
  EXPECT_THROW(evaluate_sdf_error(mesh, null_map, sdf_samples()), Error);
  const NamedMap maps[] = {{"fine", fine.get()}};
  EXPECT_THROW(evaluate_sdf_error(TriangleMesh{}, maps, sdf_samples()), Error);
  EXPECT_THROW(evaluate_sdf_error(mesh, maps, sdf_samples(0)), Error);
  SdfErrorParams p = sdf_samples();
  p.min_weight = 0;
  EXPECT_THROW(evaluate_sdf_error(mesh, maps, p), Error);
}

}  // namespace
}  // namespace hivox

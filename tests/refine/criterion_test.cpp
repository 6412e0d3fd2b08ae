// The complexity criteria (refine_kernels.h: detail and the paper's det-cov) on blocks filled
// with known fields.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

#include "hivox/refine/params.h"
#include "refine/refine_kernels.h"

namespace hivox {
namespace {

constexpr float kVoxelM = 0.004f;
constexpr float kMuM = 0.024f;

// A block at the origin whose voxel at position p (metres) holds f(p) (units of the truncation),
// observed 10 times.
std::vector<TsdfVoxel> block_of(const std::function<float(const Vec3f&)>& f) {
  std::vector<TsdfVoxel> v(kBlockVoxels);
  for (int i = 0; i < kBlockVoxels; ++i) {
    const Vec3i q = voxel_coords(i);
    v[static_cast<std::size_t>(i)].tsdf =
        tsdf_from_float(std::clamp(f({q.x * kVoxelM, q.y * kVoxelM, q.z * kVoxelM}), -1.0f, 1.0f));
    v[static_cast<std::size_t>(i)].weight = 10;
  }
  return v;
}

// Signed distance (metres) to a tilted plane through the block's middle.
float plane_distance(const Vec3f& p) {
  const Vec3f n = normalized(Vec3f{0.3f, 0.2f, 1.0f});
  return dot(n, p) - dot(n, Vec3f{0.014f, 0.014f, 0.014f});
}

// Signed distance (metres, positive outside) to the region x < 14 mm, z < 14 mm and, with
// `corner`, y < 14 mm.
float box_distance(const Vec3f& p, bool corner) {
  const float dx = p.x - 0.014f, dy = corner ? p.y - 0.014f : -1.0f, dz = p.z - 0.014f;
  const float ox = std::max(dx, 0.0f), oy = std::max(dy, 0.0f), oz = std::max(dz, 0.0f);
  const float outside = std::sqrt(ox * ox + oy * oy + oz * oz);
  return outside > 0.0f ? outside : std::max(dx, std::max(dy, dz));
}

TEST(DetailCriterion, APlaneHasNoDetail) {
  const auto v = block_of([](const Vec3f& p) { return plane_distance(p) / kMuM; });
  const float detail = kernels::block_detail_m(v.data(), kMuM, 2, 4);
  ASSERT_GE(detail, 0.0f) << "the plane crosses the block: enough samples to judge";
  EXPECT_LT(detail, 5e-6f);
}

// A plane fused from two views, one head-on and one at 55 degrees incidence: each frame stores
// the projective distance (the true one over cos(incidence)) clamped at the truncation, so the
// slanted view saturates first and the fused field bends at |F| = (1 + cos 55°) / 2 = 0.79. The
// bend is not detail of the surface: a flat table top seen at such angles stayed split for it.
TEST(DetailCriterion, ASlantedViewsClampIsNotDetail) {
  const float cos_slanted = std::cos(55.0f * 3.14159265f / 180.0f);
  const auto v = block_of([&](const Vec3f& p) {
    const float t = plane_distance(p) / kMuM;
    return 0.5f * (std::clamp(t, -1.0f, 1.0f) + std::clamp(t / cos_slanted, -1.0f, 1.0f));
  });
  const float detail = kernels::block_detail_m(v.data(), kMuM, 2, 4);
  ASSERT_GE(detail, 0.0f);
  EXPECT_LT(detail, 5e-6f);
}

// A 90-degree edge (the table's rim) crossing the block: detail well above the default split
// threshold, which is what keeps such blocks fine.
TEST(DetailCriterion, AnEdgeIsDetail) {
  const auto v = block_of([](const Vec3f& p) { return box_distance(p, false) / kMuM; });
  const float detail = kernels::block_detail_m(v.data(), kMuM, 2, 4);
  EXPECT_GT(detail, RefineParams{}.split_threshold);
}

TEST(DetailCriterion, TooLittleSurfaceIsNotJudged) {
  const auto far = block_of([](const Vec3f&) { return 1.0f; });  // free space, saturated
  EXPECT_EQ(kernels::block_detail_m(far.data(), kMuM, 2, 4), -1.0f);
  auto unseen = block_of([](const Vec3f& p) { return plane_distance(p) / kMuM; });
  for (TsdfVoxel& x : unseen) x.weight = 1;  // observed fewer than min_weight times
  EXPECT_EQ(kernels::block_detail_m(unseen.data(), kMuM, 2, 4), -1.0f);
}

// Unmeshable cells: a horizontal plane at z = 14 mm seen at a grazing angle, where only voxels
// at most 1 mm behind it (along the normal) were ever updated. Voxel rows z = 0..12 mm lie 2 mm
// or more behind: unobserved. The 7 x 7 cells between rows 12 and 16 mm have observed corners
// in front (F = 2 mm / mu) and unobserved ones: exactly those cannot be meshed.
TEST(UnmeshableCells, AGrazingViewLeavesTheCellsBehindTheSurfaceUnobserved) {
  auto grazing = block_of([](const Vec3f& p) { return (p.z - 0.014f) / kMuM; });
  for (int i = 0; i < kBlockVoxels; ++i)
    if (voxel_coords(i).z * kVoxelM - 0.014f < -0.001f)
      grazing[static_cast<std::size_t>(i)].weight = 0;
  EXPECT_EQ(kernels::block_unmeshable_cells(grazing.data(), 1), 7 * 7);
  EXPECT_EQ(kernels::block_unmeshable_cells(grazing.data(), 10), 7 * 7);  // observed 10 times
  EXPECT_EQ(kernels::block_unmeshable_cells(grazing.data(), 11), 0) << "too few observations";
}

TEST(UnmeshableCells, ObservedOrUnseenSurfacesHaveNone) {
  const auto plane = block_of([](const Vec3f& p) { return plane_distance(p) / kMuM; });
  EXPECT_EQ(kernels::block_unmeshable_cells(plane.data(), 1), 0) << "every corner observed";
  auto unseen = plane;
  for (TsdfVoxel& x : unseen) x.weight = 0;
  EXPECT_EQ(kernels::block_unmeshable_cells(unseen.data(), 1), 0) << "nothing observed";
  // Seen head-on: the band reaches mu behind the surface; beyond, cells are unobserved but their
  // observed corners lie behind the surface too (F < 0), where no surface is missing.
  auto head_on = block_of([](const Vec3f& p) { return (p.z - 0.026f) / 0.012f; });
  for (int i = 0; i < kBlockVoxels; ++i)
    if (voxel_coords(i).z * kVoxelM - 0.026f < -0.012f)
      head_on[static_cast<std::size_t>(i)].weight = 0;
  EXPECT_EQ(kernels::block_unmeshable_cells(head_on.data(), 1), 0);
  auto saturated = plane;  // observed free space (F = 1) beside unobserved voxels: no surface
  for (std::size_t i = 0; i < saturated.size(); ++i) {
    saturated[i].tsdf = tsdf_from_float(1.0f);
    if (i % 2 == 0) saturated[i].weight = 0;
  }
  EXPECT_EQ(kernels::block_unmeshable_cells(saturated.data(), 1), 0);
}

// The paper's criterion (det-cov) on the same kind of blocks. Its truncation here is 8 mm, so
// most voxels lie on the plateaus (F = +1 in front, -1 behind), where the TSDF has no gradient.

constexpr float kDetCovMuM = 0.008f;

// Every gradient of an edge lies in the plane across the edge, so their covariance has rank 2:
// the determinant vanishes. Voxels on a plateau must not count: their gradient is exactly zero
// (equal int16 values). Computed as tsdf_to_float(b) - tsdf_to_float(a), a compiler may fuse
// one product with the subtraction and leave the rounding error of the other: the same tiny
// value along x, y and z, i.e. the direction (1, 1, 1) / sqrt(3), and a determinant above the
// paper's threshold (1.4e-3 here, before the fix).
TEST(DetCovCriterion, AnEdgeHasNone) {
  const auto v = block_of([](const Vec3f& p) { return box_distance(p, false) / kDetCovMuM; });
  EXPECT_LT(std::abs(kernels::block_det_cov(v.data(), 2)), 1e-7f);
}

TEST(DetCovCriterion, ACornerIsAboveThePapersThreshold) {
  const auto v = block_of([](const Vec3f& p) { return box_distance(p, true) / kDetCovMuM; });
  EXPECT_GT(kernels::block_det_cov(v.data(), 2), 1e-4f);
}

TEST(DetCovCriterion, APlateauHasNone) {
  for (const float f : {1.0f, -1.0f}) {
    const auto v = block_of([f](const Vec3f&) { return f; });
    EXPECT_EQ(kernels::block_det_cov(v.data(), 2), 0.0f) << "F = " << f;
  }
}

}  // namespace
}  // namespace hivox

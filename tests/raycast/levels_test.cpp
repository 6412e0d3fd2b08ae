// Raycasting and interpolation where levels meet: an exact scene stored at two
// resolutions split by the plane x = 0 (finest level for x > 0, coarsest for x < 0).

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "analytic_scene.h"
#include "hivox/fusion/integrator.h"
#include "hivox/raycast/raycaster.h"
#include "map/sample_kernels.h"
#include "map/split_util.h"
#include "raycast/packet_util.h"

namespace hivox {
namespace {

constexpr float kVoxel = 0.004f;  // finest; coarsest is 16 mm
constexpr float kMu = 0.048f;     // 3 coarse voxels
constexpr DepthRange kLevelsRange{0.2f, 2.0f};

PinholeCamera camera() {
  return {160.0f, 160.0f, 79.5f, 59.5f, 160, 120};
}

struct MixedScene {
  test::SphereOnPlane shape;
  std::unique_ptr<VoxelBlockMap> map;
};

// Fuses the sphere on its floor, splitting every block with x > 0 down to the finest level, and
// fuses again so the fine blocks carry fine observations.
MixedScene make_mixed() {
  MixedScene s;
  s.shape.centre = {0.0, 0.0, 0.25};
  MapParams mp;
  mp.voxel_size_m = kVoxel;
  mp.levels = 3;
  mp.max_blocks = 1 << 17;
  mp.truncation_m = kMu;
  s.map = std::make_unique<VoxelBlockMap>(mp);
  FusionParams fp;
  fp.depth_range = kLevelsRange;
  TsdfIntegrator integrator(fp);
  const auto poses = test::orbit(s.shape.centre, 0.9, 0.5, 24);
  auto fuse_all = [&] {
    for (const Pose& T_wc : poses) {
      const DepthImage depth = s.shape.render(camera(), T_wc);
      FusionInput in{.depth_m = &depth, .rig = CameraRig::registered(camera()), .T_wc = T_wc};
      integrator.fuse(*s.map, in);
    }
  };
  fuse_all();
  test::split_down(
      *s.map, 2, [](const BlockRef& b) { return b.pos.x >= 0; }, 0.1f);
  fuse_all();
  return s;
}

const MixedScene& scene() {
  static const MixedScene s = make_mixed();
  return s;
}

RaycastParams raycast_params() {
  return RaycastParams{};
}

// Looking along +y at the sphere, so x = 0 runs down the middle of the image.
Pose side_view() {
  return look_at({0.0, -0.9, 0.75}, scene().shape.centre, Eigen::Vector3d::UnitZ());
}

TEST(Levels, TheSceneReallyHasTwoLevelsMeetingAtXZero) {
  int64_t fine_right = 0, coarse_left = 0, other = 0;
  for (const BlockRef& b : scene().map->allocated_blocks()) {
    if (b.level == 0 && b.pos.x >= 0)
      ++fine_right;
    else if (b.level == 2 && b.pos.x < 0)
      ++coarse_left;
    else
      ++other;
  }
  EXPECT_GT(fine_right, 500);
  EXPECT_GT(coarse_left, 20);
  EXPECT_EQ(other, 0);
}

TEST(Levels, InterpolationIsContinuousAcrossTheBoundary) {
  const MapView v = scene().map->view();
  kernels::BlockLookupCache cache;
  // Lines along x through the band of the floor (beside the sphere: the 5 cm gap under it is
  // thinner than 2 mu) and of the sphere's top, crossing x = 0.
  int lines = 0, crossings = 0;
  double worst_jump = 0.0, worst_error = 0.0;
  struct Line {
    double y, z;
  };
  std::vector<Line> set;
  for (int i = 0; i < 5; ++i)
    for (double z : {0.004, 0.012}) set.push_back({0.30 + 0.05 * i, z});
  for (int i = 0; i < 5; ++i)
    for (double z : {0.445, 0.455}) set.push_back({-0.04 + 0.02 * i, z});
  for (const Line& line : set) {
    float prev = 0.0f;
    bool have_prev = false;
    for (int k = 0; k <= 200; ++k) {
      const double x = -0.05 + 0.0005 * k, y = line.y, z = line.z;
      kernels::TsdfSample s;
      int level;
      const Vec3f p{static_cast<float>(x), static_cast<float>(y), static_cast<float>(z)};
      if (!kernels::sample_tsdf(v, cache, p, 1, &s, &level)) {
        have_prev = false;
        continue;
      }
      // A projective TSDF overstates distances seen at an angle, so its values are only right
      // at the crossing: where the line crosses zero, the crossing must lie on the true surface
      // (within half a voxel of the level storing it).
      if (have_prev && (s.f > 0) != (prev > 0)) {
        const double t = prev / (prev - s.f);
        const double xc = x - 0.0005 * (1.0 - t);
        crossings++;
        worst_error = std::max(worst_error, std::abs(scene().shape.sdf(Eigen::Vector3d(xc, y, z))) /
                                                (kVoxel * (1 << level)));
      }
      if (have_prev)
        worst_jump = std::max(worst_jump, std::abs(static_cast<double>(s.f - prev)) * kMu);
      prev = s.f;
      have_prev = true;
    }
    ++lines;
  }
  EXPECT_EQ(lines, 20);
  // Steps of 0.5 mm: the field changes by ~0.5 mm (|grad| ~ 1 near the surface), plus, at the
  // boundary, the disagreement of the two resolutions (a fraction of a coarse voxel); a crack
  // (a failed or default sample) would jump by up to mu = 48 mm.
  EXPECT_LT(worst_jump, 0.25 * 4 * kVoxel) << "largest step between samples 0.5 mm apart, metres";
  EXPECT_GE(crossings, 10);
  EXPECT_LT(worst_error, 0.5) << "crossings off the true surface, local voxels";
}

TEST(Levels, SamplesOneVoxelAheadEqualThreeSingleSamples) {
  // The raycaster's normals take F(p + h e_k) from one gather of the 3x3x3 voxels around p;
  // wherever that gather succeeds it must give what three separate samples give, at block
  // borders (p anywhere in its block) and beside the level boundary alike.
  const MapView v = scene().map->view();
  kernels::BlockLookupCache cache;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> x(-0.2f, 0.2f), y(-0.2f, 0.6f), z(-0.01f, 0.5f);
  int gathered = 0, declined = 0;
  for (int i = 0; i < 200000 && gathered < 2000; ++i) {
    const Vec3f p{x(rng), y(rng), z(rng)};
    kernels::TsdfSample s;
    int level;
    if (!kernels::sample_tsdf(v, cache, p, 1, &s, &level) || std::abs(s.f) > 0.5f) continue;
    Vec3f ahead;
    if (!kernels::samples_one_voxel_ahead(v, cache, level, p, 1, &ahead)) {
      ++declined;
      continue;
    }
    ++gathered;
    for (int k = 0; k < 3; ++k) {
      Vec3f a = p;
      a[k] += v.level[level].voxel_size_m;
      kernels::TsdfSample sa;
      ASSERT_TRUE(kernels::sample_trilinear(v, cache, level, a, 1, &sa)) << "axis " << k;
      EXPECT_NEAR(ahead[k], sa.f, 1e-5f) << "axis " << k << " at level " << level;
    }
  }
  EXPECT_EQ(gathered, 2000);
  EXPECT_GT(declined, 0) << "points next to the level boundary must be declined";
}

TEST(Levels, RaycastAcrossLevelsMatchesTheExactScene) {
  Raycaster raycaster(raycast_params());
  const Pose T_wc = side_view();
  const RaycastResult& r = raycaster.raycast(*scene().map, camera(), T_wc, kLevelsRange);
  const DepthImage truth = scene().shape.render(camera(), T_wc);
  int checked = 0, missed = 0, fine = 0, coarse = 0;
  std::vector<double> errors;  // distance to the true surface, in voxels of the local level
  // Mean normal errors in degrees, per surface (floor, sphere), per level, away from the level
  // boundary or beside it (where the voxels one voxel ahead lie at two levels: the normal is then
  // the gradient of the hit's interpolant, kernels::tsdf_normal).
  struct Mean {
    double sum = 0.0;
    int n = 0;
    void add(double a) {
      sum += a;
      ++n;
    }
    Mean with(const Mean& o) const { return {sum + o.sum, n + o.n}; }
    double get() const { return n > 0 ? sum / n : 0.0; }
  };
  enum { kFloor, kSphere };
  Mean away[2][3], beside[2][3];
  kernels::BlockLookupCache cache;
  for (int y = 0; y < 120; ++y)
    for (int x = 0; x < 160; ++x) {
      if (truth(x, y) <= 0.0f || truth(x, y) > 1.8f) continue;
      if (!r.hit(x, y)) {
        ++missed;
        continue;
      }
      const Vec3f pw = r.points_w(x, y);
      const Eigen::Vector3d p(pw.x, pw.y, pw.z);
      const int level = r.levels(x, y);
      (level == 0 ? fine : coarse)++;
      const double local_voxel = kVoxel * (1 << level);
      // The sphere's contact with the floor (gap 5 cm < 2 mu) is not representable: skip it.
      const double to_sphere = (p - scene().shape.centre).norm() - scene().shape.radius;
      if (std::max(to_sphere, p.z()) < 2 * kMu) continue;
      errors.push_back(std::abs(scene().shape.sdf(p)) / local_voxel);
      ++checked;
      const Eigen::Vector3d n =
          p.z() < 0.01 ? Eigen::Vector3d::UnitZ() : (p - scene().shape.centre).normalized();
      const Eigen::Vector3d view = (p - T_wc.translation()).normalized();
      // Normals on smooth parts facing the camera (at grazing angles a projective TSDF's
      // gradient is poorly defined at any resolution).
      if ((p.z() > 0.3 || (p.z() < 0.01 && std::abs(p.x()) > 0.02)) && -n.dot(view) > 0.5) {
        const Vec3f nr = r.normals_w(x, y);
        const double angle =
            std::acos(std::clamp(n.dot(Eigen::Vector3d(nr.x, nr.y, nr.z)), -1.0, 1.0)) * 180 / M_PI;
        const int surface = p.z() < 0.01 ? kFloor : kSphere;
        Vec3f ahead;
        if (kernels::samples_one_voxel_ahead(scene().map->view(), cache, level, pw, 1, &ahead))
          away[surface][level].add(angle);
        else
          beside[surface][level].add(angle);
      }
    }
  std::sort(errors.begin(), errors.end());
  ASSERT_GT(errors.size(), 5000u);
  double mean = 0;
  for (double e : errors) mean += e;
  mean /= static_cast<double>(errors.size());
  EXPECT_LT(mean, 0.15) << "mean distance to the true surface, local voxels";
  EXPECT_LT(errors[errors.size() * 99 / 100], 0.5) << "99th percentile, local voxels";
  EXPECT_GT(fine, 2000);
  EXPECT_GT(coarse, 2000);
  EXPECT_LT(missed, (checked + missed) / 100 + 5);
  for (int surface : {kFloor, kSphere})
    for (int level : {0, 2})
      std::printf(
          "[ normals  ] %s, level %d: %.2f degrees off away from the boundary (%d), %.2f "
          "beside it (%d)\n",
          surface == kFloor ? "floor" : "sphere", level, away[surface][level].get(),
          away[surface][level].n, beside[surface][level].get(), beside[surface][level].n);
  const Mean floor_away = away[kFloor][0].with(away[kFloor][2]);
  const Mean all_away = floor_away.with(away[kSphere][0]).with(away[kSphere][2]);
  ASSERT_GT(all_away.n, 1000);
  EXPECT_LT(all_away.get(), 3.0) << "mean normal error, degrees";
  ASSERT_GT(floor_away.n, 1000);
  EXPECT_LT(floor_away.get(), 1.0) << "the floor's mean normal error, degrees";
  // The sphere's normals are off by ~6.5 degrees at 16 mm and ~11 at 4 mm away from the boundary
  // too, the floor's by 0.2-0.6: the fused field around the sphere is not a distance field
  // (projective distances from 24 views, truncated), and the gradient of a hit's own cell is as
  // far off (7.9 and 12.8 degrees; the TSDF at the hits is 0 within 5e-4). Beside the boundary
  // (the hits there are the coarse level's, whose cells reach into the fine region) they are
  // 8.5: the boundary costs ~2 degrees, judged against the same surface at the same level. (The
  // mean over every surface away from the boundary, 1.9 degrees, is mostly the floor's: against
  // it, the sphere's points beside the boundary once read as 7.6 degrees off for 1.9.)
  ASSERT_GT(beside[kSphere][2].n, 100);
  ASSERT_GT(away[kSphere][2].n, 100);
  EXPECT_LT(away[kSphere][2].get(), 9.0) << "the sphere's mean normal error at 16 mm, degrees";
  EXPECT_LT(beside[kSphere][2].get(), 1.5 * away[kSphere][2].get())
      << "the sphere's mean normal error beside the level boundary against away from it, degrees";
}

// Packets whose cells reach across the level boundary sample those cells ray by ray.
TEST(Levels, RayPacketsGiveTheRayByRayResultAcrossLevels) {
  const RaycastParams rp = raycast_params();
  const Pose T_wc = side_view();
  const DepthImage truth = scene().shape.render(camera(), T_wc);
  test::expect_packets_match(*scene().map, rp, camera(), T_wc, truth, 12000, nullptr, kLevelsRange);
  test::expect_packets_match(*scene().map, rp, camera(), T_wc, test::mixed_hints(truth, kMu), 12000,
                             nullptr, kLevelsRange);
}

// Where levels meet, a cell's corners lie up to a coarse voxel apart: the surface boxes, grown by
// that much, still hold every surface.
TEST(Levels, SurfaceTilesChangeNoPixelAcrossLevels) {
  const RaycastParams rp = raycast_params();
  const Pose T_wc = side_view();
  const DepthImage hint = test::mixed_hints(scene().shape.render(camera(), T_wc), kMu);
  test::expect_surface_tiles_change_nothing(*scene().map, rp, camera(), T_wc, 12000, nullptr,
                                            nullptr, kLevelsRange);
  test::expect_surface_tiles_change_nothing(*scene().map, rp, camera(), T_wc, 12000, &hint, nullptr,
                                            kLevelsRange);
}

TEST(Levels, NoSeamInTheRenderedSurface) {
  Raycaster raycaster(raycast_params());
  // Looking down at the floor: a plane whose depth changes linearly across the image; the
  // level boundary x = 0 crosses it. A seam shows as a kink in depth along image rows.
  const Pose T_wc = look_at({0.0, -0.6, 0.6}, {0.0, 0.15, 0.0}, Eigen::Vector3d::UnitZ());
  const RaycastResult& r = raycaster.raycast(*scene().map, camera(), T_wc, kLevelsRange);
  double worst_at_boundary = 0.0, worst_elsewhere = 0.0;
  for (int y = 70; y < 120; ++y)
    for (int x = 1; x < 159; ++x) {
      if (!r.hit(x - 1, y) || !r.hit(x, y) || !r.hit(x + 1, y)) continue;
      const Vec3f p = r.points_w(x, y);
      if (p.z > 0.02 || (Eigen::Vector3d(p.x, p.y, p.z) - scene().shape.centre).norm() < 0.35)
        continue;
      const double kink = std::abs(r.depth_m(x - 1, y) - 2 * r.depth_m(x, y) + r.depth_m(x + 1, y));
      (std::abs(p.x) < 0.02 ? worst_at_boundary : worst_elsewhere) =
          std::max(std::abs(p.x) < 0.02 ? worst_at_boundary : worst_elsewhere, kink);
    }
  EXPECT_GT(worst_elsewhere, 0.0);
  EXPECT_LT(worst_at_boundary, 0.002) << "second difference of depth across the boundary, metres";
  EXPECT_LT(worst_at_boundary, 3.0 * worst_elsewhere + 0.0005) << "no worse than elsewhere";
}

}  // namespace
}  // namespace hivox

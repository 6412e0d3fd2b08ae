#include "hivox/raycast/raycaster.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

#include "analytic_scene.h"
#include "core/parallel.h"
#include "hivox/core/error.h"
#include "hivox/fusion/integrator.h"
#include "map/map_access.h"
#include "raycast/coarse_occupancy.h"
#include "raycast/packet_util.h"
#include "raycast/raycast_kernels.h"
#include "raycast/surface_tiles.h"

namespace hivox {
namespace {

// The depth range of the raycasts below (the default one).
constexpr DepthRange kRange{0.2f, 3.0f};

// Beyond this, the test scene's floor is seen only at grazing angles (see the tests).
constexpr float kWellObservedDepth = 2.0f;

// Camera-frame ray of pixel (x, y), scaled to unit depth.
Eigen::Vector3d pixel_ray_c(const PinholeCamera& cam, int x, int y) {
  return {(x - cam.cx) / cam.fx, (y - cam.cy) / cam.fy, 1.0};
}

// True when the surface seen at depth `d` along the pixel's ray is more than `gap_m` from the
// scene's other surface: in the gap under the sphere (thinner than the truncation band) the
// fused TSDF of the two surfaces overlaps and no raycast is well defined.
bool well_separated(const test::SphereOnPlane& shape, const PinholeCamera& cam, const Pose& T_wc,
                    int x, int y, float d, double gap_m) {
  const Eigen::Vector3d p = T_wc * (pixel_ray_c(cam, x, y) * d);
  const double to_sphere = (p - shape.centre).norm() - shape.radius;
  const double to_floor = p.z() - shape.floor_z;
  return std::max(to_sphere, to_floor) > gap_m;
}

PinholeCamera small_camera() {
  return {160.0f, 160.0f, 79.5f, 59.5f, 160, 120};
}

MapParams fixed_grid(float voxel_m) {
  MapParams p;
  p.voxel_size_m = voxel_m;
  p.levels = 1;
  p.max_blocks = 1 << 16;
  p.buckets_per_level = 1 << 16;
  p.excess_per_level = 1 << 14;
  return p;
}

struct Scene {
  test::SphereOnPlane shape;
  std::unique_ptr<VoxelBlockMap> map;
  float voxel = 0.01f, mu = 0.04f;
};

Scene fused_scene(float voxel, float mu_voxels = 4.0f) {
  Scene s;
  s.voxel = voxel;
  s.mu = mu_voxels * voxel;
  MapParams mp = fixed_grid(voxel);
  mp.truncation_m = s.mu;
  s.map = std::make_unique<VoxelBlockMap>(mp);
  TsdfIntegrator integrator;
  const PinholeCamera cam = small_camera();
  for (const Pose& T_wc : test::orbit(s.shape.centre, 0.9, 0.5, 24)) {
    const DepthImage depth = s.shape.render(cam, T_wc);
    FusionInput in{.depth_m = &depth, .rig = CameraRig::registered(cam), .T_wc = T_wc};
    integrator.fuse(*s.map, in);
  }
  return s;
}

Eigen::Vector3d exact_normal(const test::SphereOnPlane& shape, const Eigen::Vector3d& p) {
  const double e = 1e-5;
  Eigen::Vector3d g;
  for (int k = 0; k < 3; ++k) {
    Eigen::Vector3d d = Eigen::Vector3d::Zero();
    d[k] = e;
    g[k] = shape.sdf(p + d) - shape.sdf(p - d);
  }
  return g.normalized();
}

// Cosine between the pixel's ray and the surface normal at depth `d`: near 0 the ray grazes the
// surface (a silhouette), where whether a raycast hits depends on where its samples fall.
double ray_incidence(const test::SphereOnPlane& shape, const PinholeCamera& cam, const Pose& T_wc,
                     int x, int y, float d) {
  const Eigen::Vector3d ray_c = pixel_ray_c(cam, x, y);
  const Eigen::Vector3d p = T_wc * (ray_c * d);
  return std::abs(exact_normal(shape, p).dot(T_wc.rotation() * ray_c.normalized()));
}

// Depth along the pixel's ray where it meets the floor plane (+inf if it does not).
double floor_depth(const test::SphereOnPlane& shape, const PinholeCamera& cam, const Pose& T_wc,
                   int x, int y) {
  const Eigen::Vector3d dir = T_wc.rotation() * pixel_ray_c(cam, x, y);
  if (dir.z() >= 0) return std::numeric_limits<double>::infinity();
  return (shape.floor_z - T_wc.translation().z()) / dir.z();
}

TEST(Raycaster, HitsLieOnTheExactSurfaceWithItsNormals) {
  const Scene s = fused_scene(0.01f);
  RaycastParams rp;
  Raycaster raycaster(rp);
  const PinholeCamera cam = small_camera();
  // A viewpoint between two fused views.
  const Pose T_wc = test::orbit(s.shape.centre, 0.9, 0.5, 48)[5];
  const DepthImage truth = s.shape.render(cam, T_wc);
  RaycastStats stats;
  const RaycastResult& r = raycaster.raycast(*s.map, cam, T_wc, kRange, {}, &stats);
  int surface_pixels = 0, missed = 0, hits = 0, normals = 0, spurious = 0, all_hits = 0;
  double sum_dist = 0, max_dist = 0, sum_angle = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      all_hits += r.hit(x, y);
      // The infinite floor is seen from the orbit only at grazing angles beyond ~2 m, and near
      // the 3 m depth limit its band is cut off: judge the well-observed part.
      if (truth(x, y) > kWellObservedDepth) continue;
      const bool expected = truth(x, y) > 0.0f && truth(x, y) <= kRange.max_m;
      surface_pixels += expected;
      if (!r.hit(x, y)) {
        missed += expected;
        continue;
      }
      spurious += !expected;
      ++hits;
      const Vec3f pw = r.points_w(x, y);
      const Eigen::Vector3d p(pw.x, pw.y, pw.z);
      // Where the hit is, not how deep: at grazing angles depth errors grow as 1/cos.
      const double dist = std::abs(s.shape.sdf(p));
      sum_dist += dist;
      max_dist = std::max(max_dist, dist);
      // Depth along the optical axis agrees with the hit point.
      EXPECT_NEAR(r.depth_m(x, y), r.point_c(x, y).z, 1e-4f);
      // Normals on smooth parts: the upper sphere and the floor near it (the crease below the
      // sphere is thinner than the truncation band and cannot be represented).
      const bool upper_sphere = p.z() > s.shape.centre.z();
      const double r_floor = (p - s.shape.centre).head<2>().norm();
      const bool near_floor = p.z() < 0.01 && r_floor > 0.3 && r_floor < 0.7;
      if (upper_sphere || near_floor) {
        const Eigen::Vector3d n = exact_normal(s.shape, p);
        const Vec3f nr = r.normals_w(x, y);
        EXPECT_NEAR(norm(nr), 1.0f, 1e-4f);
        sum_angle += std::acos(std::clamp(n.dot(Eigen::Vector3d(nr.x, nr.y, nr.z)), -1.0, 1.0)) *
                     180.0 / M_PI;
        ++normals;
      }
    }
  ASSERT_GT(surface_pixels, 12000);
  EXPECT_LT(missed, surface_pixels / 100) << "surface pixels without a hit";
  EXPECT_EQ(spurious, 0) << "hits where there is no surface";
  EXPECT_EQ(stats.hits, all_hits);
  EXPECT_LT(sum_dist / hits, 0.1 * s.voxel) << "mean distance of hits to the true surface";
  EXPECT_LT(max_dist, 0.5 * s.voxel);
  ASSERT_GT(normals, 4000);
  EXPECT_LT(sum_angle / normals, 5.0) << "mean normal error, degrees";
}

TEST(Raycaster, NoSurfaceWhereNothingWasObserved) {
  const Scene s = fused_scene(0.01f);
  RaycastParams rp;
  Raycaster raycaster(rp);
  // Looking away from everything that was fused.
  const Pose T_wc = look_at({0, 0, 3}, {0, 0, 10}, Eigen::Vector3d::UnitY());
  RaycastStats stats;
  const RaycastResult& r = raycaster.raycast(*s.map, small_camera(), T_wc, kRange, {}, &stats);
  EXPECT_EQ(stats.hits, 0);
  EXPECT_EQ(r.levels(10, 10), -1);
}

// A sliver of unobserved voxels in front of a surface, such as a split leaves along a boundary
// with a coarser level: the rays that step over the positive side into the band behind the
// surface still find the surface, on it, whether a thin positive layer is left in front of the
// surface, the sliver reaches down to it or the surface lies in it (the crossing then lies
// across the sliver, a voxel layer thick).
TEST(Raycaster, FindsTheSurfaceBehindASliverOfUnobservedVoxels) {
  const PinholeCamera cam = small_camera();
  struct Sliver {
    double from_voxels, to_voxels;  ///< above the floor: unobserved between
    double farthest_voxels;         ///< the hits' largest distance to the floor
  };
  // (With the layer just in front of the surface unobserved, from 0.5 to 1.5 voxels, the floor
  // is found on 86 % of these pixels, 46 % before the search along the gradient: a march that
  // reaches the band behind the surface through an octant it skips and a sample on the sliver
  // can still end behind the crossing's cells.)
  for (const Sliver& sliver : {Sliver{1.5, 4.0, 0.5}, Sliver{-0.5, 0.5, 1.25}}) {
    const double from_vox = sliver.from_voxels, to_vox = sliver.to_voxels;
    SCOPED_TRACE(fmt::format("unobserved from {} to {} voxels above the floor", from_vox, to_vox));
    // The band 12 voxels deep, as the default map's (24 mm from 2 mm).
    Scene s = fused_scene(0.005f, 12.0f);
    Raycaster raycaster(RaycastParams{});
    const Pose T_wc = test::orbit(s.shape.centre, 0.9, 0.5, 48)[5];
    const RaycastResult before = raycaster.raycast(*s.map, cam, T_wc, kRange);
    // The slab over the floor, away from the sphere (its band stays whole).
    int64_t cleared = 0;
    for (const BlockRef& b : s.map->allocated_blocks()) {
      TsdfVoxel* v = MapAccess::tsdf(*s.map, b.ptr);
      for (int i = 0; i < kBlockVoxels; ++i) {
        const Vec3i j = voxel_coords(i);
        const Eigen::Vector3d p =
            (Eigen::Vector3d(b.pos.x * 8 + j.x, b.pos.y * 8 + j.y, b.pos.z * 8 + j.z)) *
            static_cast<double>(s.voxel);
        const double above = (p.z() - s.shape.floor_z) / s.voxel;
        const double to_sphere = (p - s.shape.centre).norm() - s.shape.radius;
        if (above > from_vox && above < to_vox && to_sphere > 2 * s.mu && v[i].weight > 0) {
          v[i].weight = 0;
          ++cleared;
        }
      }
      MapAccess::refresh_surface(*s.map, b.ptr);
    }
    ASSERT_GT(cleared, 10000);
    const RaycastResult& after = raycaster.raycast(*s.map, cam, T_wc, kRange);
    // The floor's pixels: hit on the floor before, not grazed, and nearer than 1.6 m (farther,
    // the floor's band behind it was observed too thin for any crossing across the sliver).
    int64_t floor = 0, missed = 0;
    double worst = 0.0;
    for (int y = 0; y < cam.height; ++y)
      for (int x = 0; x < cam.width; ++x) {
        if (!before.hit(x, y) || before.depth_m(x, y) > 1.6f) continue;
        const Vec3f p = before.points_w(x, y);
        const Eigen::Vector3d pw(p.x, p.y, p.z);
        if (std::abs(pw.z() - s.shape.floor_z) > 0.5 * s.voxel ||
            (pw - s.shape.centre).norm() - s.shape.radius < 2 * s.mu ||
            ray_incidence(s.shape, cam, T_wc, x, y, before.depth_m(x, y)) < 0.2)
          continue;
        ++floor;
        if (!after.hit(x, y)) {
          ++missed;
          continue;
        }
        const Vec3f q = after.points_w(x, y);
        worst = std::max(worst, static_cast<double>(std::abs(q.z - s.shape.floor_z)));
      }
    std::printf("[ sliver   ] %lld floor pixels, %lld missed, hits at most %.2f voxels off it\n",
                static_cast<long long>(floor), static_cast<long long>(missed), worst / s.voxel);
    ASSERT_GT(floor, 3000);
    EXPECT_LE(missed, floor / 1000);
    EXPECT_LE(worst, sliver.farthest_voxels * s.voxel);
  }
}

TEST(Raycaster, PointsAndNormalsInCameraFrame) {
  const Scene s = fused_scene(0.01f);
  RaycastParams rp;
  Raycaster raycaster(rp);
  const PinholeCamera cam = small_camera();
  const Pose T_wc = test::orbit(s.shape.centre, 0.9, 0.5, 24)[3];
  const RaycastResult& r = raycaster.raycast(*s.map, cam, T_wc, kRange);
  int checked = 0;
  for (int y = 0; y < cam.height; y += 7)
    for (int x = 0; x < cam.width; x += 7) {
      if (!r.hit(x, y)) continue;
      const Vec3f pc = r.point_c(x, y);
      EXPECT_NEAR(pc.z, r.depth_m(x, y), 1e-4f);
      const Vec2f uv = cam.project(pc);
      EXPECT_NEAR(uv.x, x, 1e-2f);
      EXPECT_NEAR(uv.y, y, 1e-2f);
      EXPECT_LT(r.normal_c(x, y).z, 0.05f);  // facing the camera
      ++checked;
    }
  EXPECT_GT(checked, 100);
}

// Pixels where raycasts with different hints must agree: the surface is well observed, apart
// from the scene's other surface, and not seen at a grazing angle (see the helpers above).
bool hints_agree_here(const Scene& s, const PinholeCamera& cam, const Pose& T_wc,
                      const DepthImage& truth, int x, int y) {
  const float d = truth(x, y);
  if (d > kWellObservedDepth) return false;
  if (d > 0 && !well_separated(s.shape, cam, T_wc, x, y, d, 2 * s.mu)) return false;
  return !(d > 0 && ray_incidence(s.shape, cam, T_wc, x, y, d) < 0.2);
}

// `a` and `b` hit the same pixels where hints must agree, on the exact surface.
int expect_same_surfaces(const Scene& s, const PinholeCamera& cam, const Pose& T_wc,
                         const DepthImage& truth, const RaycastResult& a, const RaycastResult& b) {
  int both = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      if (!hints_agree_here(s, cam, T_wc, truth, x, y)) continue;
      EXPECT_EQ(a.hit(x, y), b.hit(x, y)) << x << "," << y;
      if (!a.hit(x, y) || !b.hit(x, y)) continue;
      ++both;
      // Same surface: both points lie on it (samples differ, so depths differ slightly).
      for (const RaycastResult* r : {&a, &b}) {
        const Vec3f p = r->points_w(x, y);
        EXPECT_LT(std::abs(s.shape.sdf(Eigen::Vector3d(p.x, p.y, p.z))), 0.5 * s.voxel);
      }
    }
  return both;
}

// The hint tests' view of the fused scene, and its true depth.
struct HintView {
  Scene s = fused_scene(0.01f);
  RaycastParams rp;
  PinholeCamera cam = small_camera();
  Pose T_wc = test::orbit(s.shape.centre, 0.9, 0.5, 24)[7];
  DepthImage truth = s.shape.render(cam, T_wc);
};

TEST(Raycaster, StartHintSpeedsUpButNeverHidesASurface) {
  const HintView v;
  const auto& [s, rp, cam, T_wc, truth] = v;
  Raycaster plain(rp), hinted(rp), misled(rp);
  const RaycastResult& a = plain.raycast(*s.map, cam, T_wc, kRange);
  // The true depth as hint: same surface everywhere.
  const RaycastResult& b = hinted.raycast(*s.map, cam, T_wc, kRange, {&truth});
  // A hint far behind every surface (and one on unobserved pixels): the fallback must search
  // in front of it and find the same surface.
  DepthImage wrong = truth;
  for (std::size_t i = 0; i < wrong.size(); ++i)
    wrong.data()[i] = wrong.data()[i] > 0 ? 2.9f : 0.0f;
  const RaycastResult& c = misled.raycast(*s.map, cam, T_wc, kRange, {&wrong});
  EXPECT_GT(expect_same_surfaces(s, cam, T_wc, truth, a, b), 12000);
  EXPECT_GT(expect_same_surfaces(s, cam, T_wc, truth, a, c), 12000);
  const DepthImage small(10, 10);
  EXPECT_THROW(plain.raycast(*s.map, cam, T_wc, kRange, {&small}), Error);
  EXPECT_THROW(plain.raycast(*s.map, cam, T_wc, kRange, {&truth, &small}), Error);
}

// A fallback hint is searched where the start hint has none or the search at it fails: with
// start hints in free space 40 cm in front of every surface (where the search gives up) and the
// true depth as fallback, rays find their surface at the fallback instead of marching, and the
// surfaces found are those found without any hint. With the roles swapped, the search at the
// fallback fails where it is taken, and the marches find the same surfaces again.
TEST(Raycaster, FallbackHintIsSearchedWhereTheHintFails) {
  const HintView v;
  const auto& [s, rp, cam, T_wc, truth] = v;
  DepthImage in_front = truth;
  for (std::size_t i = 0; i < in_front.size(); ++i)
    in_front.data()[i] = in_front.data()[i] > 0 ? in_front.data()[i] - 0.4f : 0.0f;
  Raycaster plain(rp), rescued(rp), swapped(rp);
  const RaycastResult& a = plain.raycast(*s.map, cam, T_wc, kRange);
  RaycastStats rescued_stats, swapped_stats;
  EXPECT_GT(expect_same_surfaces(
                s, cam, T_wc, truth, a,
                rescued.raycast(*s.map, cam, T_wc, kRange, {&in_front, &truth}, &rescued_stats)),
            12000);
  EXPECT_GT(rescued_stats.found_at_fallback, 0.95 * rescued_stats.hits);
  EXPECT_GT(expect_same_surfaces(
                s, cam, T_wc, truth, a,
                swapped.raycast(*s.map, cam, T_wc, kRange, {&truth, &in_front}, &swapped_stats)),
            12000);
  EXPECT_LT(swapped_stats.found_at_fallback, swapped_stats.hits / 1000);
  EXPECT_GT(swapped_stats.found_at_hint, 0.98 * swapped_stats.hits);
}

// Which hint a ray searches first: the start hint, unless the fallback agrees with it (then the
// fallback, which is free of sensor noise); hints whose search would start outside the pixel's
// range do not count.
TEST(Raycaster, RayHintsSearchAnAgreeingFallbackFirst) {
  using kernels::RayOutcome;
  const float z_min = 0.5f, z_max = 2.0f;
  struct Case {
    const char* what;
    float start, fallback, agreement_m;
    float hint, second;  // expected
    bool first_is_fallback, second_is_fallback;
  };
  const Case cases[] = {
      {"no fallback", 1.0f, 0.0f, 0.02f, 1.0f, 0.0f, false, false},
      {"only a fallback", 0.0f, 1.0f, 0.02f, 1.0f, 0.0f, true, false},
      {"a fallback 10 cm behind: another surface, second", 1.0f, 1.1f, 0.02f, 1.0f, 1.1f, false,
       true},
      {"1.5 cm apart: one surface, the fallback first", 1.0f, 1.015f, 0.02f, 1.015f, 1.0f, true,
       false},
      {"the same depth, searched once", 1.0f, 1.0f, 0.02f, 1.0f, 0.0f, false, false},
      {"1.5 cm apart with the rule off", 1.0f, 1.015f, 0.0f, 1.0f, 1.015f, false, true},
      {"starts in front of the range, or behind it", 0.52f, 2.1f, 0.02f, 0.0f, 0.0f, false, false},
  };
  for (const Case& c : cases) {
    kernels::RayMarchConstants k;
    k.hint_margin_m = 0.04f;
    k.hint_agreement_m = c.agreement_m;
    const kernels::RayHints h = kernels::ray_hints(c.start, c.fallback, k, z_min, z_max);
    EXPECT_EQ(h.hint, c.hint) << c.what;
    EXPECT_EQ(h.second, c.second) << c.what;
    if (h.hint > 0.0f) {
      EXPECT_EQ(h.found_at_fallback(RayOutcome::AtHint), c.first_is_fallback) << c.what;
    }
    if (h.second > 0.0f) {
      EXPECT_EQ(h.found_at_fallback(RayOutcome::AtSecondHint), c.second_is_fallback) << c.what;
    }
    EXPECT_FALSE(h.found_at_fallback(RayOutcome::Marched)) << c.what;
    EXPECT_FALSE(h.found_at_fallback(RayOutcome::Miss)) << c.what;
  }
}

// With the true depth as fallback and a start hint off by up to half a band, the rays find their
// surface at the fallback, and the same surfaces as without hints.
TEST(Raycaster, AgreeingHintsFindTheSurfaceAtTheFallback) {
  const HintView v;
  const auto& [s, rp, cam, T_wc, truth] = v;
  DepthImage noisy = truth;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x)
      if (noisy(x, y) > 0.0f) noisy(x, y) += ((x + y) % 2 == 0 ? 0.5f : -0.5f) * s.mu;
  Raycaster plain(rp), hinted(rp);
  RaycastStats stats;
  const RaycastResult& a = plain.raycast(*s.map, cam, T_wc, kRange);
  EXPECT_GT(
      expect_same_surfaces(s, cam, T_wc, truth, a,
                           hinted.raycast(*s.map, cam, T_wc, kRange, {&noisy, &truth}, &stats)),
      12000);
  EXPECT_GT(stats.found_at_fallback, 0.95 * stats.hits);
  RaycastParams start_first = rp;
  start_first.hint_agreement_mu = 0.0f;
  Raycaster noisy_first(start_first);
  EXPECT_GT(expect_same_surfaces(
                s, cam, T_wc, truth, a,
                noisy_first.raycast(*s.map, cam, T_wc, kRange, {&noisy, &truth}, &stats)),
            12000);
  EXPECT_LT(stats.found_at_fallback, 0.05 * stats.hits);
}

TEST(Raycaster, RayPacketsGiveTheRayByRayResult) {
  const Scene s = fused_scene(0.01f);
  RaycastParams rp;
  const PinholeCamera cam = small_camera();
  for (int view : {3, 7, 15}) {
    const Pose T_wc = test::orbit(s.shape.centre, 0.9, 0.5, 24)[view];
    const DepthImage truth = s.shape.render(cam, T_wc);
    test::expect_packets_match(*s.map, rp, cam, T_wc, truth, 12000);
    test::expect_packets_match(*s.map, rp, cam, T_wc, test::mixed_hints(truth, s.mu), 12000);
    // Where the search at the hint fails, the search at the fallback hint.
    test::expect_packets_match(*s.map, rp, cam, T_wc, test::mixed_hints(truth, s.mu), 12000,
                               &truth);
  }
}

// The grid of super-blocks (4x4x4 blocks of the coarsest level) holding blocks: exactly those
// with a block of any level are marked, across negative coordinates, and points map to the
// super-block their blocks map to.
TEST(CoarseOccupancy, MarksTheSuperBlocksHoldingBlocksOfAnyLevel) {
  MapParams p = fixed_grid(0.01f);
  p.levels = 2;  // blocks of 8 and 16 cm, super-blocks of 64 cm
  VoxelBlockMap map(p);
  const std::vector<BlockKey> keys = {{{-1, 0, 0}, 0}, {{-9, 3, 7}, 0}, {{5, 5, 5}, 1}};
  ASSERT_EQ(map.insert_blocks(keys).inserted, 3);
  std::vector<int32_t> cells;
  const kernels::CoarseOccupancy grid = kernels::build_coarse_occupancy(map, &cells);
  ASSERT_NE(grid.cells, nullptr);
  EXPECT_FLOAT_EQ(grid.side_m, 0.64f);
  // Fine block (-1, 0, 0): super-block floor(-1 / 8) = -1; (-9, 3, 7): (-2, 0, 0); coarse block
  // (5, 5, 5): floor(5 / 4) = 1.
  EXPECT_EQ(grid.lo, (Vec3i{-2, 0, 0}));
  EXPECT_EQ(grid.dims, (Vec3i{4, 2, 2}));
  int marked = 0;
  for (int z = -1; z <= 2; ++z)
    for (int y = -1; y <= 2; ++y)
      for (int x = -3; x <= 2; ++x) {
        const Vec3i c{x, y, z};
        const bool holds = c == Vec3i{-1, 0, 0} || c == Vec3i{-2, 0, 0} || c == Vec3i{1, 1, 1};
        EXPECT_EQ(!grid.empty(c), holds) << x << " " << y << " " << z;
        marked += !grid.empty(c);
      }
  EXPECT_EQ(marked, 3);
  // A point inside each block lies in its block's super-block.
  for (const BlockKey& k : keys) {
    const float block_m = map.view().level[k.level].block_size_m;
    const Vec3f inside = (to_float(k.pos) + Vec3f{0.5f, 0.5f, 0.5f}) * block_m;
    EXPECT_FALSE(grid.empty(grid.cell_of(inside)));
  }
  // An empty map has no grid.
  VoxelBlockMap empty(p);
  EXPECT_EQ(kernels::build_coarse_occupancy(empty, &cells).cells, nullptr);
}

// The device keeps the super-blocks' bounds across frames, grown only by insertions: that holds
// because a split's children and a merge's parent lie in the super-block of the blocks they
// replace, at every level and on both sides of zero.
TEST(CoarseOccupancy, RefinementKeepsBlocksInTheirSuperBlock) {
  constexpr int kLevels = 3;
  for (int level = 1; level < kLevels; ++level)
    for (int x = -70; x <= 70; x += 3)
      for (int y : {-33, -1, 0, 5})
        for (int z : {-9, 0, 17}) {
          const Vec3i parent{x, y, z};
          const Vec3i expected = kernels::CoarseOccupancy::super_block_of(parent, level, kLevels);
          for (int c = 0; c < 8; ++c) {
            const Vec3i child{2 * x + (c & 1), 2 * y + ((c >> 1) & 1), 2 * z + (c >> 2)};
            ASSERT_EQ(kernels::CoarseOccupancy::super_block_of(child, level - 1, kLevels), expected)
                << "parent " << x << " " << y << " " << z << " at level " << level;
          }
        }
}

// Bounds grown by many threads at once (the device's insertions) are the serial bounds; a map's
// bounds, and the grid over them, are those its blocks give by hand.
TEST(CoarseOccupancy, BoundsGrownConcurrentlyAreTheSerialBounds) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> coord(-500, 500);
  std::vector<Vec3i> cells(20000);
  for (Vec3i& c : cells) c = {coord(rng), coord(rng), coord(rng)};
  kernels::SuperBlockBounds serial, concurrent;
  EXPECT_TRUE(serial.empty());
  for (const Vec3i& c : cells) serial.add(c);
  parallel_for(static_cast<int64_t>(cells.size()),
               [&](int64_t i) { concurrent.add_atomic(cells[static_cast<std::size_t>(i)]); });
  EXPECT_EQ(concurrent.lo, serial.lo);
  EXPECT_EQ(concurrent.hi, serial.hi);
  EXPECT_FALSE(concurrent.empty());

  MapParams p = fixed_grid(0.01f);
  p.levels = 2;
  VoxelBlockMap map(p);
  const std::vector<BlockKey> keys = {{{-1, 0, 0}, 0}, {{-9, 3, 7}, 0}, {{5, 5, 5}, 1}};
  ASSERT_EQ(map.insert_blocks(keys).inserted, 3);
  const kernels::SuperBlockBounds b =
      kernels::super_block_bounds(map.view().meta, map.block_high_water(), map.levels());
  EXPECT_EQ(b.lo, (Vec3i{-2, 0, 0}));
  EXPECT_EQ(b.hi, (Vec3i{1, 1, 1}));
  const kernels::CoarseOccupancy laid =
      kernels::CoarseOccupancy::covering(b, map.view().level[1].block_size_m);
  EXPECT_EQ(laid.lo, (Vec3i{-2, 0, 0}));
  EXPECT_EQ(laid.dims, (Vec3i{4, 2, 2}));
  EXPECT_FLOAT_EQ(laid.side_m, 0.64f);  // 4 blocks of 16 cm
  EXPECT_EQ(laid.cell_count(), 16);
  EXPECT_EQ(laid.cells, nullptr);
  EXPECT_EQ(kernels::CoarseOccupancy::covering({}, 0.16f).cell_count(), 0);
}

// Crossing empty super-blocks in one step finds the surfaces block-by-block marching finds.
TEST(Raycaster, CoarseSkippingFindsTheSameSurfaces) {
  const Scene s = fused_scene(0.01f);
  std::vector<int32_t> cells;
  const kernels::CoarseOccupancy grid = kernels::build_coarse_occupancy(*s.map, &cells);
  ASSERT_NE(grid.cells, nullptr);
  const int64_t empty = std::count(cells.begin(), cells.end(), 0);
  EXPECT_GT(empty, static_cast<int64_t>(cells.size()) / 4);  // there is space to skip
  RaycastParams rp;
  const PinholeCamera cam = small_camera();
  for (int view : {2, 9}) {
    // From farther out than the views fused, so that rays cross empty space first.
    const Pose T_wc = test::orbit(s.shape.centre, 1.6, 0.7, 24)[view];
    rp.tuning.coarse_skipping = true;
    Raycaster skipping(rp);
    rp.tuning.coarse_skipping = false;
    Raycaster block_by_block(rp);
    test::expect_same_raycast(skipping.raycast(*s.map, cam, T_wc, kRange),
                              block_by_block.raycast(*s.map, cam, T_wc, kRange), 8000,
                              "skipping vs block by block");
  }
}

// A march split across a warp's 32 lanes (each a stretch of the ray, the lowest lane's hit kept;
// the GPU's way with the few rays of a warp whose hints failed) finds the surfaces the whole
// march finds, on the exact surface: without a hint, with the hint at the surface, in front of it
// and behind it (where the march behind the hint begins behind the surface and the front wins).
TEST(Raycaster, SplitMarchesFindTheSurfacesWholeMarchesFind) {
  const Scene s = fused_scene(0.01f);
  const MapView view = s.map->view();
  std::vector<int32_t> cells;
  RaycastParams rp;
  const kernels::RayMarchConstants k =
      kernels::march_constants(rp, view, kernels::build_coarse_occupancy(*s.map, &cells));
  const PinholeCamera cam = small_camera();
  std::vector<kernels::BlockLookupCache> caches(32);
  kernels::BlockLookupCache cache;
  int64_t rays = 0, both = 0, one_only = 0, apart = 0, off_surface = 0;
  for (int v : {2, 9}) {
    const Pose T_wc = test::orbit(s.shape.centre, 1.6, 0.7, 24)[v];
    const DepthImage truth = s.shape.render(cam, T_wc);
    const Rigid3f T = to_rigid3f(T_wc);
    for (int y = 0; y < cam.height; y += 2)
      for (int x = 0; x < cam.width; x += 2) {
        const float d = truth(x, y);
        const Vec3f dir = T.rotate(cam.ray(static_cast<float>(x), static_cast<float>(y)));
        std::vector<float> hints = {0.0f};  // none
        if (d > 0.0f) hints.insert(hints.end(), {d, d - 3.0f * s.mu, d + 3.0f * s.mu});
        for (const float hint : hints) {
          ++rays;
          kernels::RayHit whole, split;
          const bool a = kernels::march_from_hint(view, cache, T.t, dir, hint, kRange.min_m,
                                                  kRange.max_m, k, &whole);
          const bool b = kernels::split_march_on_cpu(view, caches.data(), T.t, dir, hint,
                                                     kRange.min_m, kRange.max_m, k, 32, &split);
          one_only += a != b;
          if (!a || !b) continue;
          ++both;
          apart += std::abs(whole.depth_m - split.depth_m) > 0.5f * s.voxel;
          const Vec3f p = split.p_w;
          off_surface += std::abs(s.shape.sdf(Eigen::Vector3d(p.x, p.y, p.z))) > 0.5 * s.voxel;
        }
      }
  }
  std::printf(
      "[ split    ] %lld rays: %lld hit by both marches, %lld by one only, %lld hits "
      "more than half a voxel apart, %lld split hits off the surface\n",
      static_cast<long long>(rays), static_cast<long long>(both), static_cast<long long>(one_only),
      static_cast<long long>(apart), static_cast<long long>(off_surface));
  EXPECT_GT(both, rays / 4);
  EXPECT_LE(one_only, rays / 500);
  EXPECT_LE(apart, both / 500);
  EXPECT_LE(off_surface, both / 500);
}

// Marching only where a ray crosses its tile's surface boxes finds what marching the whole range
// finds: without hints (every ray marches), and with hints that fail (their rays march from in
// front of the hint, and in front of that where they find nothing).
TEST(Raycaster, SurfaceTilesChangeNoPixel) {
  const Scene s = fused_scene(0.01f);
  RaycastParams rp;
  const PinholeCamera cam = small_camera();
  for (int view : {2, 9}) {
    const Pose T_wc = test::orbit(s.shape.centre, 1.6, 0.7, 24)[view];
    test::expect_surface_tiles_change_nothing(*s.map, rp, cam, T_wc, 5000);
  }
  for (int view : {3, 14}) {
    const Pose T_wc = test::orbit(s.shape.centre, 0.9, 0.5, 24)[view];
    const DepthImage truth = s.shape.render(cam, T_wc);
    const DepthImage hint = test::mixed_hints(truth, s.mu);
    test::expect_surface_tiles_change_nothing(*s.map, rp, cam, T_wc, 12000, &hint);
    test::expect_surface_tiles_change_nothing(*s.map, rp, cam, T_wc, 12000, &hint, &truth);
  }
}

// A box's tile rectangle holds the tile of every pixel that sees a point of the box within the
// depth range (points sampled in random boxes around the camera, many out of view or straddling
// the image's borders, the depth limits or the camera plane); boxes entirely out of view are
// rejected.
TEST(RangeTiles, BoxTileRectHoldsEveryPixelThatSeesTheBox) {
  const PinholeCamera cam = small_camera();
  const kernels::RangeTiles tiles = kernels::RangeTiles::covering(8, cam);
  const Pose T_wc = look_at({0.3, -0.2, 0.5}, {1.0, 1.5, 0.2}, Eigen::Vector3d::UnitZ());
  const Rigid3f T_cw = to_rigid3f(T_wc.inverse());
  const float min_depth = 0.2f, max_depth = 3.0f;
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> coord(-3.5f, 3.5f), size(0.01f, 0.3f), unit(0.0f, 1.0f);
  int accepted = 0, rejected = 0;
  for (int b = 0; b < 4000; ++b) {
    const Vec3f origin{coord(rng), coord(rng), coord(rng)};
    const float side = size(rng);
    kernels::TileRect rect;
    const bool in_view =
        kernels::box_tile_rect(T_cw, cam, origin, side, min_depth, max_depth, tiles, &rect);
    accepted += in_view;
    rejected += !in_view;
    for (int i = 0; i < 200; ++i) {
      const Vec3f p = T_cw * (origin + Vec3f{unit(rng), unit(rng), unit(rng)} * side);
      if (p.z < min_depth || p.z > max_depth) continue;
      const Vec2f uv = cam.project(p);
      const int x = static_cast<int>(std::floor(uv.x + 0.5f));
      const int y = static_cast<int>(std::floor(uv.y + 0.5f));
      if (x < 0 || y < 0 || x >= cam.width || y >= cam.height) continue;
      ASSERT_TRUE(in_view) << "box " << b << " is seen at pixel " << x << " " << y;
      EXPECT_TRUE(x / 8 >= rect.tx0 && x / 8 <= rect.tx1 && y / 8 >= rect.ty0 && y / 8 <= rect.ty1)
          << "box " << b;
    }
  }
  EXPECT_GT(accepted, 100);
  EXPECT_GT(rejected, 1000);
}

// Every surface a raycast finds lies within the stretch of its ray that the surface boxes of its
// tile give, while most rays that pass beside the surfaces get no stretch at all.
TEST(SurfaceTiles, HoldEverySurfaceARayMeets) {
  const Scene s = fused_scene(0.01f);
  RaycastParams rp;
  rp.tuning.surface_tiles = SurfaceTileUse::Never;
  const PinholeCamera cam = small_camera();
  const Pose T_wc = test::orbit(s.shape.centre, 1.6, 0.7, 24)[5];
  Raycaster raycaster(rp);
  const RaycastResult& r = raycaster.raycast(*s.map, cam, T_wc, kRange);

  kernels::RangeTiles tiles = kernels::RangeTiles::covering(rp.tuning.range_tile_px, cam);
  std::vector<float> z_min(static_cast<std::size_t>(tiles.count()), FLT_MAX);
  std::vector<float> z_max(static_cast<std::size_t>(tiles.count()), 0.0f);
  tiles.z_min = z_min.data();
  tiles.z_max = z_max.data();
  const Rigid3f T_cw = to_rigid3f(T_wc.inverse());
  kernels::fill_range_tiles(*s.map, cam, T_cw, kRange.min_m, kRange.max_m, tiles);
  kernels::SurfaceTileStorage storage;
  const Rigid3f T = to_rigid3f(T_wc);
  const kernels::SurfaceTiles surface = kernels::build_surface_tiles(
      *s.map, cam, T_cw, T.t, tiles, kRange.min_m, kRange.max_m, &storage);
  ASSERT_FALSE(surface.empty());

  int hits = 0, in_range_misses = 0, spared = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const int t = tiles.tile_of(x, y);
      const Vec3f dir = T.rotate(cam.ray(static_cast<float>(x), static_cast<float>(y)));
      float z_in = 0, z_out = 0;
      const bool crosses = surface.ray_stretch(t, kernels::inverse_direction(dir), z_min[t],
                                               z_max[t], &z_in, &z_out);
      if (r.hit(x, y)) {
        ++hits;
        ASSERT_TRUE(crosses) << "pixel " << x << " " << y;
        EXPECT_LE(z_in, r.depth_m(x, y));
        EXPECT_GE(z_out, r.depth_m(x, y));
      } else if (z_min[t] < z_max[t]) {
        ++in_range_misses;  // a march over the tile's range that finds nothing
        spared += !crosses;
      }
    }
  EXPECT_GT(hits, 5000);
  ASSERT_GT(in_range_misses, 500);
  EXPECT_GT(spared, in_range_misses / 2) << "misses spared their march";
  std::printf("%d hits; of %d misses in a tile's range, %d cross no surface box\n", hits,
              in_range_misses, spared);
}

// The surface near a ray's measured depth, found from the hint alone: a hint anywhere inside the
// band around the surface leads to the surface the march finds, and whatever the hint, a hit is
// on the surface; a hint in unobserved space behind the surface gives up (the caller marches), or,
// near the sphere's rim where the band behind it was seen from other poses, walks back to the
// surface the march finds.
TEST(Raycaster, HitNearHintFindsTheSurfaceFromAnywhereInTheBand) {
  const Scene s = fused_scene(0.01f);
  const PinholeCamera cam = small_camera();
  const Pose T_wc = test::orbit(s.shape.centre, 0.9, 0.5, 24)[7];  // a pose that was fused
  const DepthImage truth = s.shape.render(cam, T_wc);
  const MapView view = s.map->view();
  kernels::BlockLookupCache cache;
  cache.reset();
  kernels::RayMarchConstants k;
  k.mu_m = s.mu;
  k.step_fraction = 0.8f;
  const Rigid3f T = to_rigid3f(T_wc);
  int tried = 0, found = 0, far_hits = 0, normals = 0, off_normals = 0, behind_hits = 0;
  double sum_angle = 0;
  for (int y = 0; y < cam.height; y += 3)
    for (int x = 0; x < cam.width; x += 3) {
      const float d = truth(x, y);
      if (d <= 0 || d > kWellObservedDepth ||
          !well_separated(s.shape, cam, T_wc, x, y, d, 2 * s.mu) ||
          ray_incidence(s.shape, cam, T_wc, x, y, d) < 0.2)
        continue;
      const Vec3f dir = T.rotate(cam.ray(static_cast<float>(x), static_cast<float>(y)));
      kernels::RayHit march;
      if (!kernels::march_ray(view, cache, T.t, dir, d - 2 * s.mu, d + 2 * s.mu, k, &march))
        continue;
      for (const float offset_mu : {-2.0f, -1.0f, -0.6f, -0.2f, 0.0f, 0.3f, 0.6f}) {
        const bool in_band = std::abs(offset_mu) < 1.0f;
        tried += in_band;
        kernels::RayHit hit;
        if (!kernels::hit_near_hint(view, cache, T.t, dir, d + offset_mu * s.mu, k, &hit)) continue;
        found += in_band;
        far_hits += !in_band;
        const Vec3f p = hit.p_w;
        EXPECT_LT(std::abs(s.shape.sdf(Eigen::Vector3d(p.x, p.y, p.z))), 0.5 * s.voxel);
        EXPECT_NEAR(hit.depth_m, march.depth_m, 0.5f * s.voxel);
        // Normals may differ where the hit moves within a voxel (they follow per-voxel noise, and
        // where the samples one voxel ahead are unknown they come from a fallback).
        const float angle = std::acos(std::clamp(dot(hit.normal_w, march.normal_w), -1.0f, 1.0f));
        off_normals += angle > 10.0f * 3.14159265f / 180.0f;
        sum_angle += angle;
        ++normals;
      }
      // Behind the sphere's rim the ray meets the floor again (hidden from this pose, seen from
      // others): a hint in that floor's band rightly finds it.
      if (floor_depth(s.shape, cam, T_wc, x, y) < d + 6.0f * s.mu) continue;
      kernels::RayHit behind;
      if (!kernels::hit_near_hint(view, cache, T.t, dir, d + 4.0f * s.mu, k, &behind)) continue;
      ++behind_hits;
      EXPECT_NEAR(behind.depth_m, march.depth_m, 0.5f * s.voxel) << x << "," << y;
    }
  EXPECT_GT(tried, 3000);
  EXPECT_GT(found, 0.98 * tried);
  EXPECT_LT(sum_angle / normals, 1.0 * 3.14159265 / 180.0);
  EXPECT_LT(off_normals, normals / 1000);
  EXPECT_LT(behind_hits, tried / 100);
  std::printf(
      "hint in the band: %d of %d rays hit; a band or two in front: %d hits; 4 bands "
      "behind: %d hits\n",
      found, tried, far_hits, behind_hits);
}

// The previous frame's raycast, warped into the next view, is where that view sees the surface
// (the pipeline starts rays there where the sensor measured nothing).
TEST(Raycaster, WarpedDepthIsTheDepthSeenFromTheNewPose) {
  const Scene s = fused_scene(0.01f);
  RaycastParams rp;
  const PinholeCamera cam = small_camera();
  const Pose T_a = test::orbit(s.shape.centre, 0.9, 0.5, 24)[7];
  Raycaster ra(rp), rb(rp);
  const RaycastResult& a = ra.raycast(*s.map, cam, T_a, kRange);

  // Seen from the same pose, every hit lands on its own pixel, except where a nearer surface
  // within a pixel may hide it; a pixel without a hit stays empty unless it is a hole between
  // two opposite hits that agree within a band (filled with the nearer of them).
  DepthImage same;
  warp_raycast_depth(a, cam, T_a, s.mu, &same);
  auto hole_fill = [&](int x, int y) {
    float z = 0.0f;
    for (const auto& [dx, dy] :
         {std::pair{1, 0}, std::pair{0, 1}, std::pair{1, 1}, std::pair{1, -1}}) {
      if (!cam.contains(x - dx, y - dy) || !cam.contains(x + dx, y + dy) ||
          !a.hit(x - dx, y - dy) || !a.hit(x + dx, y + dy))
        continue;
      const float p = a.depth_m(x - dx, y - dy), q = a.depth_m(x + dx, y + dy);
      if (std::abs(p - q) <= s.mu && (z == 0.0f || std::min(p, q) < z)) z = std::min(p, q);
    }
    return z;
  };
  int kept = 0, dropped = 0, filled = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      if (!a.hit(x, y)) {
        if (same(x, y) != 0.0f) {
          ++filled;
          EXPECT_NEAR(same(x, y), hole_fill(x, y), 1e-5f * same(x, y)) << x << "," << y;
        }
        continue;
      }
      // Far away the floor is seen at grazing angles, where neighbouring pixels lie more than a
      // band apart.
      if (a.depth_m(x, y) > kWellObservedDepth) continue;
      if (same(x, y) > 0.0f) {
        ++kept;
        EXPECT_NEAR(same(x, y), a.depth_m(x, y), 1e-5f * a.depth_m(x, y)) << x << "," << y;
        continue;
      }
      ++dropped;
      float front = a.depth_m(x, y);
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
          if (cam.contains(x + dx, y + dy) && a.hit(x + dx, y + dy))
            front = std::min(front, a.depth_m(x + dx, y + dy));
      EXPECT_GT(a.depth_m(x, y) - front, s.mu) << x << "," << y;
    }
  EXPECT_GT(kept, 0.98 * (kept + dropped));
  EXPECT_LT(filled, kept / 1000);
  std::printf(
      "warp to the same pose: %d hits kept, %d behind a nearer neighbour, %d holes filled\n", kept,
      dropped, filled);

  // From a pose 1 cm and 1.5 degrees away: the warped depth is the depth raycast from there.
  Pose delta = Pose::Identity();
  delta.linear() = Eigen::AngleAxisd(1.5 * M_PI / 180.0, Eigen::Vector3d(1, 2, 0.5).normalized())
                       .toRotationMatrix();
  delta.translation() = Eigen::Vector3d(0.006, -0.005, 0.006);
  const Pose T_b = T_a * delta;
  const RaycastResult& b = rb.raycast(*s.map, cam, T_b, kRange);
  DepthImage warped;
  warp_raycast_depth(a, cam, T_b, s.mu, &warped);
  int hits = 0, covered = 0, close = 0, tight = 0, in_band = 0, other_surface = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      if (!b.hit(x, y) || b.depth_m(x, y) > kWellObservedDepth) continue;
      ++hits;
      if (!(warped(x, y) > 0.0f)) continue;
      ++covered;
      const float diff = std::abs(warped(x, y) - b.depth_m(x, y));
      close += diff < s.voxel;
      tight += diff < 0.1f * s.voxel;
      in_band += diff < s.mu;
      other_surface += diff > 2 * s.mu;
    }
  EXPECT_GT(covered, 0.945 * hits);  // 0.933 without filling the holes between landed pixels
  // Landing on the nearest pixel moves a hit by up to half a pixel, ~5 mm at 1.5 m with this
  // small camera: where the surface is oblique, more than a voxel in depth. The hit's tangent
  // plane gives the depth at the pixel's centre instead (a third of the pixels were within a
  // tenth of a voxel with the hit's own depth).
  EXPECT_GT(tight, 0.9 * covered);
  EXPECT_GT(close, 0.98 * covered);
  EXPECT_GT(in_band, 0.995 * covered);
  EXPECT_LT(other_surface, covered / 200);
  std::printf(
      "warp to a pose 1 cm, 1.5 deg away: %d of %d hits covered, %d within a tenth of a voxel, "
      "%d within a voxel, %d within a band, %d on another surface\n",
      covered, hits, tight, close, in_band, other_surface);
  EXPECT_THROW(warp_raycast_depth(a, cam, T_b, 0.0f, &warped), Error);
}

TEST(Raycaster, ParamsAreValidated) {
  RaycastParams p;
  p.tuning.range_tile_px = RaycastTuning::kMaxRangeTilePx + 1;
  EXPECT_THROW(Raycaster{p}, Error);
  const Scene s = fused_scene(0.02f);
  Raycaster raycaster;
  for (const DepthRange bad : {DepthRange{0.5f, 0.4f}, DepthRange{-0.1f, 1.0f},
                               DepthRange{0.2f, std::numeric_limits<float>::infinity()}})
    EXPECT_THROW(raycaster.raycast(*s.map, small_camera(), Pose::Identity(), bad), Error)
        << bad.min_m << " " << bad.max_m;
  p = RaycastParams{};
  p.step_fraction = 0;
  EXPECT_THROW(p.validate(), Error);
  p = RaycastParams{};
  p.hint_margin_mu = -1.0f;  // rays would start behind the hinted surface
  EXPECT_THROW(p.validate(), Error);
  p.hint_margin_mu = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(p.validate(), Error);
  p.hint_margin_mu = 0.0f;
  EXPECT_NO_THROW(p.validate());
  p.hint_agreement_mu = -0.5f;
  EXPECT_THROW(p.validate(), Error);
  p.hint_agreement_mu = 0.0f;
  EXPECT_NO_THROW(p.validate());
}

}  // namespace
}  // namespace hivox

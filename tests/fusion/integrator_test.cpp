#include "hivox/fusion/integrator.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "analytic_scene.h"
#include "hivox/core/error.h"
#include "hivox/core/threads.h"
#include "map/map_invariants.h"
#include "test_util.h"

namespace hivox {
namespace {

PinholeCamera small_camera() {
  return {160.0f, 160.0f, 79.5f, 59.5f, 160, 120};
}

MapParams fixed_grid(float voxel_m, float mu_m = MapParams{}.truncation_m) {
  MapParams p;
  p.voxel_size_m = voxel_m;
  p.truncation_m = mu_m;
  p.levels = 1;
  p.max_blocks = 1 << 16;
  p.buckets_per_level = 1 << 16;
  p.excess_per_level = 1 << 14;
  return p;
}

struct Fused {
  std::unique_ptr<VoxelBlockMap> map;
  std::vector<Allocation> allocations;
};

/// Fuses the scene's depth from each pose into a fixed grid of `voxel_m` with band `mu_m`.
Fused fuse_views(const test::SphereOnPlane& scene, float voxel_m, float mu_m,
                 const FusionParams& fp, const std::vector<Pose>& poses) {
  Fused out{std::make_unique<VoxelBlockMap>(fixed_grid(voxel_m, mu_m)), {}};
  TsdfIntegrator integrator(fp);
  const PinholeCamera cam = small_camera();
  for (const Pose& T_wc : poses) {
    const DepthImage depth = scene.render(cam, T_wc);
    FusionInput in;
    in.depth_m = &depth;
    in.rig = CameraRig::registered(cam);
    in.T_wc = T_wc;
    out.allocations.push_back(integrator.fuse(*out.map, in));
  }
  return out;
}

Fused fuse_orbit(const test::SphereOnPlane& scene, float voxel_m, float mu_m, int views,
                 double sweep = 2 * M_PI) {
  return fuse_views(scene, voxel_m, mu_m, FusionParams{},
                    test::orbit(scene.centre, 0.9, 0.5, views, 0.3, sweep));
}

Eigen::Vector3d voxel_position(const BlockRef& b, int i, float voxel_m) {
  const Vec3i v = voxel_coords(i);
  return Eigen::Vector3d(b.pos.x * 8 + v.x, b.pos.y * 8 + v.y, b.pos.z * 8 + v.z) * voxel_m;
}

/// The floor plane z = 0 alone (the sphere shrunk to nothing, out of sight).
test::SphereOnPlane floor_only() {
  test::SphereOnPlane scene;
  scene.radius = 0.0;
  scene.centre = {0, 0, -5};
  return scene;
}

TEST(Integrator, TsdfMatchesExactSdfOnASurfaceSeenAtModerateAngles) {
  // A floor plane seen from 1 m above, within ~35 degrees of its normal. The projective
  // distance along the optical axis exceeds the Euclidean one by 1/cos(angle) (< 1.22 here)
  // and the nearest-pixel look-up (where the bilinear one falls back) adds < half a pixel (~3 mm)
  // of lateral offset.
  const test::SphereOnPlane scene = floor_only();
  const float voxel = 0.01f, mu = 0.04f;
  FusionParams fp;
  fp.depth_range.max_m = 1.6f;
  std::vector<Pose> poses;
  for (int i = 0; i < 10; ++i) {
    const double a = i * 0.6;
    poses.push_back(look_at({0.3 * std::cos(a), 0.3 * std::sin(a), 1.0}, {0.05 * i - 0.2, 0, 0},
                            Eigen::Vector3d::UnitY()));
  }
  const Fused f = fuse_views(scene, voxel, mu, fp, poses);
  const VoxelBlockMap& map = *f.map;
  double sum_err = 0, max_err = 0;
  int n = 0;
  for (const BlockRef& b : map.allocated_blocks()) {
    const TsdfVoxel* vox = map.block_tsdf(b.ptr);
    for (int i = 0; i < kBlockVoxels; ++i) {
      if (vox[i].weight < 3) continue;
      const double sdf = scene.sdf(voxel_position(b, i, voxel));
      if (std::abs(sdf) > 0.5 * mu) continue;
      const double err = std::abs(tsdf_to_float(vox[i].tsdf) * mu - sdf);
      sum_err += err;
      max_err = std::max(max_err, err);
      ++n;
    }
  }
  ASSERT_GT(n, 10000);
  EXPECT_LT(sum_err / n, 0.25 * voxel) << "mean |TSDF - SDF| over " << n << " voxels";
  EXPECT_LT(max_err, 1.0 * voxel);
}

/// Fuses a floor plane seen at ~65-70 degrees from its normal and returns the mean distance of
/// the fused surface (the zero crossing along z of each observed voxel column) from the true
/// plane, in metres, over the near part of the floor (y <= 0.4 m), where the depth steps from
/// pixel to pixel (up to ~3 cm) stay under mu and bilinear sampling applies; farther away they
/// exceed mu and both samplings take the nearest pixel.
double slanted_floor_offset_m(DepthSampling sampling) {
  FusionParams fp;
  fp.depth_range.max_m = 3.0f;
  fp.depth_sampling = sampling;
  std::vector<Pose> poses;
  for (int i = 0; i < 8; ++i)
    poses.push_back(
        look_at({0.02 * i, -1.3, 0.5}, {0.03 * i - 0.1, 0.0, 0.0}, Eigen::Vector3d::UnitZ()));
  const float voxel = 0.01f;
  const Fused f = fuse_views(floor_only(), voxel, 0.04f, fp, poses);
  const VoxelBlockMap& map = *f.map;
  double sum = 0;
  int n = 0;
  for (int y = -100; y <= 40; ++y)
    for (int x = -40; x <= 40; ++x)
      for (int z = -3; z < 3; ++z) {
        const auto lo = map.voxel(0, Vec3i{x, y, z}), hi = map.voxel(0, Vec3i{x, y, z + 1});
        if (!lo || !hi || lo->weight < 4 || hi->weight < 4) continue;
        const float f_lo = tsdf_to_float(lo->tsdf), f_hi = tsdf_to_float(hi->tsdf);
        if (!(f_lo <= 0.0f && f_hi > 0.0f)) continue;
        sum += std::abs((z + f_lo / (f_lo - f_hi)) * voxel);
        ++n;
      }
  EXPECT_GT(n, 3000) << "crossings found";
  return sum / std::max(n, 1);
}

TEST(Integrator, BilinearDepthSamplingRemovesThePixelStaircase) {
  // Nearest-pixel sampling gives each voxel the depth of a pixel whose ray meets the plane up
  // to half a pixel away: on a slanted plane that is a staircase of depth steps, which the fused
  // surface keeps (~1 mm here). Bilinear sampling follows the plane between pixels.
  const double nearest = slanted_floor_offset_m(DepthSampling::Nearest);
  const double bilinear = slanted_floor_offset_m(DepthSampling::Bilinear);
  EXPECT_LT(bilinear, 0.01 * 0.01) << "within 1 % of a voxel";
  EXPECT_LT(bilinear, 0.2 * nearest)
      << "nearest " << nearest << " m, bilinear " << bilinear << " m";
}

TEST(FusionParams, DepthSamplingNamesRoundTripAndBadOnesAreNamed) {
  for (const DepthSampling d : {DepthSampling::Nearest, DepthSampling::Bilinear})
    EXPECT_EQ(parse_depth_sampling(to_string(d)), d);
  try {
    parse_depth_sampling("linear");
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::InvalidArgument);
    EXPECT_TRUE(test::contains(e.what(), "'linear'")) << e.what();
  }
}

TEST(Integrator, ZeroCrossingsLieOnTheTrueSurface) {
  // Sphere on a floor seen from all around: wherever two neighbouring observed voxels change
  // sign, the linearly interpolated crossing must lie on the exact surface.
  const test::SphereOnPlane scene;
  const float voxel = 0.01f, mu = 0.04f;
  const Fused f = fuse_orbit(scene, voxel, mu, 24);
  double sum_err = 0, max_err = 0;
  int n = 0;
  for (const BlockRef& b : f.map->allocated_blocks()) {
    for (int i = 0; i < kBlockVoxels; ++i) {
      const Vec3i c = voxel_coords(i);
      const Vec3i g{b.pos.x * 8 + c.x, b.pos.y * 8 + c.y, b.pos.z * 8 + c.z};
      const auto va = f.map->voxel(0, g);
      if (!va || va->weight < 3) continue;
      for (int axis = 0; axis < 3; ++axis) {
        Vec3i h = g;
        h[axis] += 1;
        const auto vb = f.map->voxel(0, h);
        if (!vb || vb->weight < 3) continue;
        const float fa = tsdf_to_float(va->tsdf), fb = tsdf_to_float(vb->tsdf);
        if ((fa > 0) == (fb > 0)) continue;
        Eigen::Vector3d x(g.x, g.y, g.z);
        x[axis] += fa / (fa - fb);
        const double err = std::abs(scene.sdf(x * voxel));
        sum_err += err;
        max_err = std::max(max_err, err);
        ++n;
      }
    }
  }
  ASSERT_GT(n, 10000);
  EXPECT_LT(sum_err / n, 0.1 * voxel) << "mean distance of " << n << " crossings";
  EXPECT_LT(max_err, 0.5 * voxel);
}

TEST(Integrator, SignIsPositiveInFrontAndNegativeBehind) {
  const test::SphereOnPlane scene;
  const float voxel = 0.01f, mu = 0.04f;
  const Fused f = fuse_orbit(scene, voxel, mu, 12);
  int wrong = 0, n = 0;
  for (const BlockRef& b : f.map->allocated_blocks()) {
    const TsdfVoxel* vox = f.map->block_tsdf(b.ptr);
    for (int i = 0; i < kBlockVoxels; ++i) {
      if (vox[i].weight == 0) continue;
      const double sdf = scene.sdf(voxel_position(b, i, voxel));
      if (std::abs(sdf) < 1.5 * voxel) continue;
      ++n;
      wrong += (sdf > 0) != (vox[i].tsdf > 0);
    }
  }
  ASSERT_GT(n, 1000);
  EXPECT_LT(wrong, n / 200) << wrong << " of " << n << " voxels have the wrong sign";
  test::expect_map_consistent(*f.map);  // with every block's surface summary
}

TEST(Integrator, AllocatesOnlyTheTruncationBand) {
  const test::SphereOnPlane scene;
  const float voxel = 0.01f, mu = 0.03f;
  const Fused f = fuse_orbit(scene, voxel, mu, 8);
  const double block = 8 * voxel;
  const double half_diag = std::sqrt(3.0) * block / 2;
  for (const BlockRef& b : f.map->allocated_blocks()) {
    const Eigen::Vector3d centre =
        (Eigen::Vector3d(b.pos.x, b.pos.y, b.pos.z) + Eigen::Vector3d::Constant(0.5)) * block;
    // A block is allocated only when some ray's band [d - mu, d + mu] crosses it; the band is
    // at most mu / cos(angle) from the surface. Generous bound: mu * 3 + half the block diagonal.
    EXPECT_LT(std::abs(scene.sdf(centre)), 3 * mu + half_diag);
  }
  // Every visible surface point has its block: sample the sphere's upper half.
  int missing = 0;
  for (int i = 0; i < 500; ++i) {
    const double a = 2 * M_PI * i / 500.0, e = 0.2 + 1.0 * ((i * 37) % 100) / 100.0;
    const Eigen::Vector3d p =
        scene.centre + scene.radius * Eigen::Vector3d(std::cos(a) * std::cos(e),
                                                      std::sin(a) * std::cos(e), std::sin(e));
    const Vec3i bp{static_cast<int>(std::floor(p.x() / block)),
                   static_cast<int>(std::floor(p.y() / block)),
                   static_cast<int>(std::floor(p.z() / block))};
    missing += !f.map->find(0, bp).has_value();
  }
  EXPECT_EQ(missing, 0);
}

TEST(Integrator, ParallelAllocationEqualsSerial) {
  const test::SphereOnPlane scene;
  auto blocks_with = [&](int threads) {
    set_thread_count(threads);
    const Fused f = fuse_orbit(scene, 0.005f, 0.02f, 6);
    test::expect_map_consistent(*f.map);
    std::vector<BlockKey> keys;
    for (const BlockRef& b : f.map->allocated_blocks()) keys.push_back({b.pos, b.level});
    std::sort(keys.begin(), keys.end());
    return std::make_pair(keys, f.allocations);
  };
  const auto [serial, s1] = blocks_with(1);
  const auto [parallel, s2] = blocks_with(3);
  set_thread_count(0);
  EXPECT_EQ(serial, parallel);
  ASSERT_EQ(s1.size(), s2.size());
  for (std::size_t i = 0; i < s1.size(); ++i) {
    EXPECT_EQ(s1[i].visible_blocks.size(), s2[i].visible_blocks.size());
    EXPECT_EQ(s1[i].stats.new_blocks, s2[i].stats.new_blocks);
  }
}

TEST(Integrator, VisibleBlocksAreUniqueAndNewBlocksCounted) {
  const test::SphereOnPlane scene;
  const Fused f = fuse_orbit(scene, 0.01f, 0.04f, 4, M_PI / 4);
  int64_t total_new = 0;
  for (const Allocation& a : f.allocations) {
    const AllocationStats& s = a.stats;
    EXPECT_GT(s.valid_pixels, 1000);
    EXPECT_LE(s.new_blocks, static_cast<int64_t>(a.visible_blocks.size()));
    EXPECT_EQ(s.dropped_blocks, 0);
    total_new += s.new_blocks;
    std::vector<int32_t> ptrs;
    for (const BlockRef& b : a.visible_blocks) ptrs.push_back(b.ptr);
    std::sort(ptrs.begin(), ptrs.end());
    EXPECT_EQ(std::adjacent_find(ptrs.begin(), ptrs.end()), ptrs.end()) << "a block twice";
  }
  EXPECT_EQ(total_new, f.map->blocks_in_use());
  // The second view of a nearly identical pose allocates few new blocks.
  EXPECT_LT(f.allocations[1].stats.new_blocks, f.allocations[0].stats.new_blocks);
}

TEST(Integrator, FullPoolDropsAreCountedAndFusionContinues) {
  const test::SphereOnPlane scene;
  MapParams mp = fixed_grid(0.005f);
  mp.max_blocks = 100;
  VoxelBlockMap map(mp);
  TsdfIntegrator integrator;
  const PinholeCamera cam = small_camera();
  const Pose T_wc = test::orbit(scene.centre, 0.9, 0.5, 1)[0];
  const DepthImage depth = scene.render(cam, T_wc);
  FusionInput in{.depth_m = &depth, .rig = CameraRig::registered(cam)};
  in.T_wc = T_wc;
  const Allocation a = integrator.fuse(map, in);
  EXPECT_EQ(map.blocks_in_use(), 100);
  EXPECT_GT(a.stats.dropped_blocks, 0);
  EXPECT_EQ(map.dropped_blocks(), a.stats.dropped_blocks);
  EXPECT_EQ(a.visible_blocks.size(), 100u);
  test::expect_map_consistent(map);
}

TEST(Integrator, DepthRangeIsRespected) {
  const test::SphereOnPlane scene;
  FusionParams fp;
  fp.depth_range.max_m = 0.5f;  // everything is farther: nothing to do
  TsdfIntegrator integrator(fp);
  VoxelBlockMap map(fixed_grid(0.01f));
  const PinholeCamera cam = small_camera();
  const Pose T_wc = test::orbit(scene.centre, 0.9, 0.5, 1)[0];
  const DepthImage depth = scene.render(cam, T_wc);
  FusionInput in{.depth_m = &depth, .rig = CameraRig::registered(cam)};
  in.T_wc = T_wc;
  const Allocation a = integrator.fuse(map, in);
  EXPECT_EQ(a.stats.valid_pixels, 0);
  EXPECT_EQ(map.blocks_in_use(), 0);
}

TEST(Integrator, ColourIsFusedNearTheSurface) {
  const test::SphereOnPlane scene;
  VoxelBlockMap map(fixed_grid(0.01f));
  TsdfIntegrator integrator;
  const PinholeCamera cam = small_camera();
  const Pose T_wc = test::orbit(scene.centre, 0.9, 0.5, 1)[0];
  const DepthImage depth = scene.render(cam, T_wc);
  const ColorImage color(cam.width, cam.height, Rgb8{200, 100, 50});
  FusionInput in{.depth_m = &depth, .color = &color, .rig = CameraRig::registered(cam)};
  in.T_wc = T_wc;
  integrator.fuse(map, in);
  int coloured = 0;
  for (const BlockRef& b : map.allocated_blocks())
    for (int i = 0; i < kBlockVoxels; ++i) {
      const ColorVoxel c = map.block_color(b.ptr)[i];
      if (c.weight == 0) continue;
      ++coloured;
      ASSERT_EQ(c.r, 200);
      ASSERT_EQ(c.g, 100);
      ASSERT_EQ(c.b, 50);
    }
  EXPECT_GT(coloured, 1000);
}

TEST(Integrator, BadInputIsAClearError) {
  TsdfIntegrator integrator;
  VoxelBlockMap map(fixed_grid(0.01f));
  const DepthImage depth(100, 80);
  FusionInput in{.depth_m = &depth, .rig = CameraRig::registered(small_camera())};
  try {
    integrator.fuse(map, in);
    FAIL();
  } catch (const Error& e) {
    EXPECT_TRUE(test::contains(e.what(), "100x80")) << e.what();
  }
  // Blocks to integrate that the map does not hold at those pool indices.
  const DepthImage good = test::SphereOnPlane{}.render(
      small_camera(), test::orbit(test::SphereOnPlane{}.centre, 0.9, 0.5, 1)[0]);
  FusionInput fine{.depth_m = &good, .rig = CameraRig::registered(small_camera())};
  fine.T_wc = test::orbit(test::SphereOnPlane{}.centre, 0.9, 0.5, 1)[0];
  std::vector<BlockRef> blocks = integrator.allocate(map, fine).visible_blocks;
  ASSERT_FALSE(blocks.empty());
  blocks[0].ptr = map.block_high_water();
  EXPECT_THROW(integrator.integrate(map, fine, blocks), Error);
  blocks = integrator.allocate(map, fine).visible_blocks;
  blocks[0].level = 1;
  EXPECT_THROW(integrator.integrate(map, fine, blocks), Error);
  FusionParams bad;
  bad.max_weight = 0;
  EXPECT_THROW(TsdfIntegrator{bad}, Error);
  bad = FusionParams{};
  bad.depth_range.max_m = 0.1f;
  EXPECT_THROW(bad.validate(), Error);
  MapParams no_band;
  no_band.truncation_m = -1;
  EXPECT_THROW(VoxelBlockMap{no_band}, Error);
}

}  // namespace
}  // namespace hivox

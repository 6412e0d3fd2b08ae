#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "hivox/core/error.h"
#include "hivox/map/hierarchy_edit.h"
#include "hivox/refine/refiner.h"
#include "map/map_access.h"
#include "map/map_invariants.h"

namespace hivox {
namespace {

// A level-1 block holding the plane z = 12 cm (positive above, 2 cm voxels, mu = 3 cm) as fusion
// from a camera above leaves it: the band below z = 9 cm was never observed. Split into its 8
// children, of which the upper 4 hold the plane and the lower 4 nothing observed. The children's
// `updates` are set as fusion would: `upper` for the upper ones, 0 for the lower ones (the band
// never reaches them). Returns the children.
std::vector<BlockRef> split_plane_block(VoxelBlockMap& map, uint16_t upper) {
  std::vector<BlockRef> parent;
  map.insert_blocks(std::vector<BlockKey>{{{0, 0, 0}, 1}}, &parent);
  const float s = map.params().voxel_size_at(1), mu = 0.03f;
  TsdfVoxel* v = MapAccess::tsdf(map, parent[0].ptr);
  for (int i = 0; i < kBlockVoxels; ++i) {
    const float sdf = voxel_coords(i).z * s - 0.12f;
    v[i].tsdf = tsdf_from_float(sdf / mu);
    v[i].weight = sdf >= -mu ? 20 : 0;
  }
  MapAccess::refresh_surface(map, parent[0].ptr);
  EXPECT_EQ(split_blocks(map, parent).done, 1);
  std::vector<BlockRef> children;
  for (const BlockRef& b : map.allocated_blocks()) {
    children.push_back(b);
    MapAccess::meta(map, b.ptr).updates = b.pos.z == 1 ? upper : 0;
  }
  EXPECT_EQ(children.size(), 8u);
  return children;
}

RefineParams every_frame_without_noise() {
  RefineParams rp;
  rp.noise = SensorNoise::none();
  rp.every_n_frames = 1;
  return rp;
}

// A camera 1 m above the blocks, looking down.
Pose camera_above() {
  return Pose(Eigen::Translation3d(0.08, 0.08, 1.0)) *
         Pose(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));
}

MapParams two_levels_of_1cm() {
  MapParams mp;
  mp.voxel_size_m = 0.01f;
  mp.levels = 2;
  mp.max_blocks = 64;
  return mp;
}

TEST(Refiner, AFlatParentMergesThoughItsUnobservedChildrenNeverSettle) {
  const MapParams mp = two_levels_of_1cm();
  RefineParams rp = every_frame_without_noise();
  const Pose above = camera_above();
  {
    VoxelBlockMap map(mp);
    const auto children = split_plane_block(map, rp.min_updates);
    Refiner refiner(rp);
    // The plane's children are settled and flat; the never-observed ones have no surface to judge.
    EXPECT_EQ(refiner.refine(map, children, above).merges, 1);
    EXPECT_EQ(map.blocks_per_level(), (std::vector<int64_t>{0, 1}));
    test::expect_map_consistent(map);
  }
  {
    VoxelBlockMap map(mp);
    // Children holding the surface must still settle first (fresh interpolations look flat).
    const auto children = split_plane_block(map, rp.min_updates - 1);
    Refiner refiner(rp);
    EXPECT_EQ(refiner.refine(map, children, above).merges, 0);
    EXPECT_EQ(map.blocks_per_level(), (std::vector<int64_t>{8, 0}));
  }
}

// A plane at z = 13.1 cm (positive above; mu = 3 cm) seen at a grazing angle: only voxels less
// than 6 mm behind it were ever updated.
void fill_grazing_plane(VoxelBlockMap& map, const BlockRef& b, uint16_t updates) {
  const float s = map.params().voxel_size_at(b.level), mu = 0.03f;
  TsdfVoxel* v = MapAccess::tsdf(map, b.ptr);
  for (int i = 0; i < kBlockVoxels; ++i) {
    const float sdf = (8 * b.pos.z + voxel_coords(i).z) * s - 0.131f;
    v[i].tsdf = tsdf_from_float(sdf / mu);
    v[i].weight = sdf >= -0.006f ? 20 : 0;
  }
  MapAccess::refresh_surface(map, b.ptr);
  MapAccess::meta(map, b.ptr).updates = updates;
}

// At 2 cm the voxel row below the plane (12 cm) lies 1.1 cm behind it: unobserved, so the
// surface between it and the row above (14 cm, observed) cannot be meshed, though the plane has
// no detail. The block splits; at 1 cm the row at 13 cm lies 1 mm behind and is observed.
TEST(Refiner, ABlockWhoseSurfaceItsLevelCannotMeshSplits) {
  RefineParams rp = every_frame_without_noise();
  const Pose above = camera_above();
  for (int cells : {8, 0}) {
    rp.split_unmeshable_cells = cells;
    VoxelBlockMap map(two_levels_of_1cm());
    std::vector<BlockRef> block;
    map.insert_blocks(std::vector<BlockKey>{{{0, 0, 0}, 1}}, &block);
    fill_grazing_plane(map, block[0], rp.min_updates);
    Refiner refiner(rp);
    EXPECT_EQ(refiner.refine(map, block, above).splits, cells > 0 ? 1 : 0) << cells;
  }
}

// The same plane in the children of a split level-1 block, observed as fusion at 1 cm leaves it:
// the children are flat and settled, but merged (every other voxel) the row at 12 cm would be
// the unobserved one below the surface again, so they stay split.
TEST(Refiner, SiblingsMergeOnlyWhenTheMergedBlockCanMeshTheirSurface) {
  RefineParams rp = every_frame_without_noise();
  const Pose above = camera_above();
  for (int cells : {8, 0}) {
    rp.split_unmeshable_cells = cells;
    VoxelBlockMap map(two_levels_of_1cm());
    std::vector<BlockRef> parent;
    map.insert_blocks(std::vector<BlockKey>{{{0, 0, 0}, 1}}, &parent);
    ASSERT_EQ(split_blocks(map, parent).done, 1);
    const std::vector<BlockRef> children = map.allocated_blocks();
    for (const BlockRef& b : children) fill_grazing_plane(map, b, rp.min_updates);
    Refiner refiner(rp);
    EXPECT_EQ(refiner.refine(map, children, above).merges, cells > 0 ? 0 : 1) << cells;
    test::expect_map_consistent(map);
  }
}

TEST(RefineParams, MergeLevelFollowsTheSplitLevelAndBadValuesAreRejected) {
  RefineParams p;
  // Far away the noise terms dominate the fixed thresholds: the merge level is the split level
  // of a settled block times the ratio, whatever the split factor.
  for (float factor : {0.25f, 0.1f, 0.5f}) {
    p.split_noise_factor = factor;
    const float z = 3.0f;
    const SensorNoise n = SensorNoise::kinect();
    ASSERT_GT(p.merge_level(n, z), p.merge_threshold);
    EXPECT_NEAR(p.merge_level(n, z), p.merge_noise_ratio * p.split_level(n, z), 1e-9f) << factor;
    EXPECT_LT(p.merge_level(n, z), p.split_level(n, z, 1.0f)) << "hysteresis, young blocks too";
  }
  p = RefineParams{};
  p.merge_noise_ratio = 1.5f;
  EXPECT_THROW(p.validate(), Error);
  p = RefineParams{};
  p.split_noise_factor = -0.1f;
  EXPECT_THROW(p.validate(), Error);
}

}  // namespace
}  // namespace hivox

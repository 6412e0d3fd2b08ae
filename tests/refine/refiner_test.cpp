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

TEST(Refiner, AFlatParentMergesThoughItsUnobservedChildrenNeverSettle) {
  MapParams mp;
  mp.voxel_size_m = 0.01f;
  mp.levels = 2;
  mp.max_blocks = 64;
  RefineParams rp;
  rp.noise = SensorNoise::none();
  rp.every_n_frames = 1;
  const Pose above = Pose(Eigen::Translation3d(0.08, 0.08, 1.0)) *
                     Pose(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));
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

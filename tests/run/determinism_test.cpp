// The same input gives the same map content, mesh and trajectory whatever the thread count: every
// reduction has a fixed order (ICP rows are summed in row order, allocation sorts and
// de-duplicates, extraction orders blocks by key), and where blocks land in the pool, which does
// depend on the threads' timing, changes nothing a reader sees.

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <tuple>
#include <vector>

#include "hivox/core/threads.h"
#include "hivox/io/dataset.h"
#include "hivox/mesh/extract_mesh.h"
#include "hivox/run/runner.h"
#include "hivox/synth/synthetic_dataset.h"
#include "test_util.h"

namespace hivox {
namespace {

struct Outcome {
  std::vector<StampedPose> trajectory;
  std::map<std::tuple<int, int, int, int>, std::vector<uint32_t>> blocks;  // voxels by key
  std::vector<Vec3f> mesh;
};

Outcome run_with(DatasetReader& reader, const RunParams& params, int threads) {
  set_thread_count(threads);
  const RunResult run = run_reconstruction(reader, params);
  set_thread_count(0);
  Outcome o;
  o.trajectory = run.reconstruction->trajectory();
  const VoxelBlockMap& map = run.reconstruction->map();
  for (const BlockRef& b : map.allocated_blocks()) {
    std::vector<uint32_t> words(kBlockVoxels);
    const TsdfVoxel* v = map.block_tsdf(b.ptr);
    for (int i = 0; i < kBlockVoxels; ++i)
      words[i] = static_cast<uint32_t>(static_cast<uint16_t>(v[i].tsdf)) | uint32_t{v[i].weight}
                                                                               << 16;
    o.blocks[{b.level, b.pos.x, b.pos.y, b.pos.z}] = std::move(words);
  }
  o.mesh = extract_mesh(map).positions_w;
  return o;
}

void expect_same(const Outcome& a, const Outcome& b) {
  ASSERT_EQ(a.trajectory.size(), b.trajectory.size());
  for (std::size_t i = 0; i < a.trajectory.size(); ++i)
    EXPECT_TRUE(a.trajectory[i].T_wc.matrix() == b.trajectory[i].T_wc.matrix()) << "pose " << i;
  EXPECT_EQ(a.blocks.size(), b.blocks.size());
  EXPECT_TRUE(a.blocks == b.blocks) << "the voxels of some block differ";
  ASSERT_EQ(a.mesh.size(), b.mesh.size());
  EXPECT_TRUE(a.mesh == b.mesh);
}

TEST(Determinism, OneAndTwoThreadsGiveTheSameReconstructionOfARealSequence) {
  HIVOX_REQUIRE_DATASET(dir, "tum_fr1_rpy");
  DatasetParams dp;
  dp.max_frames = 12;
  const auto reader = open_dataset(dir.string(), dp);
  RunParams p;  // tracked, 3 levels from 2 mm: every stage, refinement included
  p.reconstruction.refine.every_n_frames = 1;
  const Outcome one = run_with(*reader, p, 1);
  const Outcome two = run_with(*reader, p, 2);
  expect_same(one, two);
  EXPECT_GT(one.blocks.size(), 5000u);
}

TEST(Determinism, OneTwoAndThreeThreadsGiveTheSameReconstructionOfANoisyScene) {
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=300&noise=kinect"));
  RunParams p;
  p.max_frames = 8;
  p.reconstruction.map.voxel_size_m = 0.004f;
  p.reconstruction.map.truncation_m = 0.032f;
  p.reconstruction.refine.every_n_frames = 1;
  const Outcome one = run_with(data, p, 1);
  expect_same(one, run_with(data, p, 2));
  expect_same(one, run_with(data, p, 3));
  EXPECT_GT(one.mesh.size(), 10000u);
}

}  // namespace
}  // namespace hivox

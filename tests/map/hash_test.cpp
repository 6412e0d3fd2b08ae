#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>

#include "hivox/core/error.h"
#include "hivox/core/threads.h"
#include "hivox/map/voxel_block_map.h"
#include "map/map_invariants.h"
#include "test_util.h"

namespace hivox {
namespace {

MapParams small_params(int64_t buckets, int64_t excess, int64_t blocks, int levels = 1) {
  MapParams p;
  p.voxel_size_m = 0.01f;
  p.levels = levels;
  p.buckets_per_level = buckets;
  p.excess_per_level = excess;
  p.max_blocks = blocks;
  p.store_color = true;
  return p;
}

std::vector<BlockKey> random_keys(std::size_t n, int range, unsigned seed, int level = 0) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> d(-range, range);
  std::set<std::tuple<int, int, int>> seen;
  std::vector<BlockKey> keys;
  while (keys.size() < n) {
    const Vec3i p{d(rng), d(rng), d(rng)};
    if (seen.emplace(p.x, p.y, p.z).second) keys.push_back({p, level});
  }
  return keys;
}

TEST(Hash, InsertAndFind) {
  VoxelBlockMap map(small_params(1 << 12, 1 << 10, 4096));
  const auto keys = random_keys(2000, 50, 1);
  std::vector<BlockRef> refs;
  const InsertStats s = map.insert_blocks(keys, &refs);
  EXPECT_EQ(s.inserted, 2000);
  EXPECT_EQ(s.dropped(), 0);
  for (const BlockRef& r : refs) {
    const auto f = map.find(0, r.pos);
    ASSERT_TRUE(f.has_value());
    EXPECT_EQ(f->ptr, r.ptr);
  }
  EXPECT_FALSE(map.find(0, {1000, 1000, 1000}).has_value());
  EXPECT_EQ(map.blocks_in_use(), 2000);
  test::expect_map_consistent(map);
}

TEST(Hash, NewBlocksAreUnobserved) {
  VoxelBlockMap map(small_params(64, 64, 8));
  std::vector<BlockRef> refs;
  const BlockKey key{{3, -4, 5}, 0};
  map.insert_blocks(std::span(&key, 1), &refs);
  ASSERT_EQ(refs.size(), 1u);
  for (int i = 0; i < kBlockVoxels; ++i) {
    EXPECT_EQ(map.block_tsdf(refs[0].ptr)[i].weight, 0);
    EXPECT_EQ(map.block_color(refs[0].ptr)[i].weight, 0);
  }
}

TEST(Hash, CraftedCollisionsShareABucket) {
  // Keys chosen so that all hash to bucket 0 of a 64-bucket table.
  const uint32_t mask = 63;
  std::vector<BlockKey> colliding;
  for (int x = -200; x <= 200 && colliding.size() < 40; ++x)
    for (int y = -3; y <= 3 && colliding.size() < 40; ++y)
      if (block_hash({x, y, 7}, mask) == 0) colliding.push_back({{x, y, 7}, 0});
  ASSERT_EQ(colliding.size(), 40u);
  VoxelBlockMap map(small_params(64, 64, 128));
  const InsertStats s = map.insert_blocks(colliding);
  EXPECT_EQ(s.inserted, 40);
  EXPECT_EQ(map.excess_in_use(0), 39);  // one bucket head, 39 chained entries
  for (const BlockKey& k : colliding) EXPECT_TRUE(map.find(0, k.pos).has_value());
  // A key of the same bucket that was never inserted is not found.
  for (int x = 201;; ++x)
    if (block_hash({x, 0, 7}, mask) == 0) {
      EXPECT_FALSE(map.find(0, {x, 0, 7}).has_value());
      break;
    }
  test::expect_map_consistent(map);
}

TEST(Hash, LongChains) {
  VoxelBlockMap map(small_params(16, 4096, 4096));
  const auto keys = random_keys(3000, 40, 2);
  EXPECT_EQ(map.insert_blocks(keys).inserted, 3000);
  for (const BlockKey& k : keys) ASSERT_TRUE(map.find(0, k.pos).has_value());
  EXPECT_GE(map.excess_in_use(0), 3000 - 16);
  test::expect_map_consistent(map);
}

TEST(Hash, NegativeCoordinatesDoNotCollideWithTheirMirror) {
  const uint32_t mask = (1u << 20) - 1;
  int mirror_collisions = 0;
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> d(1, 5000);
  for (int i = 0; i < 20000; ++i) {
    const Vec3i p{d(rng), d(rng), d(rng)};
    mirror_collisions += block_hash(p, mask) == block_hash({-p.x, -p.y, -p.z}, mask);
  }
  EXPECT_LT(mirror_collisions, 5);  // ~1 in 2^20 expected, not "always"
  VoxelBlockMap map(small_params(1 << 10, 1 << 10, 64));
  const std::vector<BlockKey> keys = {
      {{1, 2, 3}, 0}, {{-1, -2, -3}, 0}, {{-1, 2, 3}, 0}, {{0, 0, -1}, 0}};
  std::vector<BlockRef> refs;
  map.insert_blocks(keys, &refs);
  ASSERT_EQ(refs.size(), 4u);
  std::set<int32_t> ptrs;
  for (const BlockKey& k : keys) ptrs.insert(map.find(0, k.pos)->ptr);
  EXPECT_EQ(ptrs.size(), 4u);
  EXPECT_FALSE(map.find(0, {0, 0, 1}).has_value());
  // Voxel coordinates: voxel -1 belongs to block -1, voxel 0 to block 0.
  EXPECT_EQ(block_of_voxel({-1, 0, 8}), (Vec3i{-1, 0, 1}));
  EXPECT_EQ(block_of_voxel({-8, -9, 7}), (Vec3i{-1, -2, 0}));
  EXPECT_EQ(local_voxel_index({-1, 0, 0}), voxel_index(7, 0, 0));
}

TEST(Hash, FullPoolIsCountedAndHarmless) {
  VoxelBlockMap map(small_params(256, 256, 50));
  const auto first = random_keys(30, 20, 4);
  std::vector<BlockRef> refs;
  ASSERT_EQ(map.insert_blocks(first, &refs).inserted, 30);
  auto more = random_keys(200, 20, 5);
  std::erase_if(more, [&](const BlockKey& k) {
    return std::find(first.begin(), first.end(), k) != first.end();
  });
  const InsertStats s = map.insert_blocks(more);
  EXPECT_EQ(s.inserted, 20);
  EXPECT_EQ(s.dropped_pool_full, static_cast<int64_t>(more.size()) - 20);
  EXPECT_EQ(map.dropped_blocks(), s.dropped());
  EXPECT_EQ(map.blocks_in_use(), 50);
  for (const BlockRef& r : refs) EXPECT_EQ(map.find(0, r.pos)->ptr, r.ptr);  // old blocks intact
  int found = 0;
  for (const BlockKey& k : more) found += map.find(0, k.pos).has_value();
  EXPECT_EQ(found, 20);  // dropped blocks left no entries behind
  test::expect_map_consistent(map);
}

TEST(Hash, FullExcessListIsCountedAndHarmless) {
  VoxelBlockMap map(small_params(4, 10, 1000));
  const auto keys = random_keys(100, 30, 6);
  const InsertStats s = map.insert_blocks(keys);
  EXPECT_LE(s.inserted, 14);
  EXPECT_GE(s.inserted, 10);
  EXPECT_EQ(s.dropped_hash_full, 100 - s.inserted);
  EXPECT_EQ(map.excess_in_use(0), 10);
  int found = 0;
  for (const BlockKey& k : keys) found += map.find(0, k.pos).has_value();
  EXPECT_EQ(found, s.inserted);
  test::expect_map_consistent(map);
}

TEST(Hash, ParallelInsertionEqualsSerial) {
  const auto keys = random_keys(60000, 60, 7);
  auto run = [&](int threads) {
    set_thread_count(threads);
    VoxelBlockMap map(small_params(1 << 10, 1 << 16, 1 << 16));  // long chains: contention
    const InsertStats s = map.insert_blocks(keys);
    EXPECT_EQ(s.inserted, 60000);
    test::expect_map_consistent(map);
    std::vector<BlockKey> got;
    for (const BlockRef& r : map.allocated_blocks()) got.push_back({r.pos, r.level});
    std::sort(got.begin(), got.end());
    return got;
  };
  const auto serial = run(1);
  const auto parallel = run(4);
  set_thread_count(0);
  EXPECT_EQ(serial, parallel);
  auto expected = keys;
  std::sort(expected.begin(), expected.end());
  EXPECT_EQ(serial, expected);
}

TEST(Hash, LevelsAreIndependentTables) {
  VoxelBlockMap map(small_params(64, 64, 64, 3));
  const std::vector<BlockKey> keys = {{{1, 1, 1}, 0}, {{1, 1, 1}, 2}};
  EXPECT_EQ(map.insert_blocks(keys).inserted, 2);
  EXPECT_TRUE(map.find(0, {1, 1, 1}).has_value());
  EXPECT_FALSE(map.find(1, {1, 1, 1}).has_value());
  EXPECT_TRUE(map.find(2, {1, 1, 1}).has_value());
  EXPECT_EQ(map.blocks_per_level(), (std::vector<int64_t>{1, 0, 1}));
  test::expect_map_consistent(map);
}

TEST(Hash, ParamsAreValidated) {
  MapParams p;
  p.buckets_per_level = 1000;
  EXPECT_THROW(VoxelBlockMap{p}, Error);
  p = MapParams{};
  p.levels = 5;
  EXPECT_THROW(p.validate(), Error);
  p = MapParams{};
  p.voxel_size_m = 0;
  try {
    p.validate();
    FAIL();
  } catch (const Error& e) {
    EXPECT_TRUE(test::contains(e.what(), "voxel_size_m")) << e.what();
  }
  p = MapParams{};
  p.truncation_m = 0;
  EXPECT_THROW(p.validate(), Error);
  p = MapParams{};
  p.max_blocks = 64;
  try {
    VoxelBlockMap on_gpu(p, Device::cuda(0));
    FAIL() << "this build keeps maps on the CPU only";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::Unsupported);
    EXPECT_TRUE(test::contains(e.what(), "cuda:0")) << e.what();
  }
}

}  // namespace
}  // namespace hivox

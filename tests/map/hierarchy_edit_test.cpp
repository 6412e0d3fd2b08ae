#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <set>
#include <tuple>

#include "hivox/core/error.h"
#include "hivox/core/threads.h"
#include "hivox/map/hierarchy_edit.h"
#include "map/map_access.h"
#include "map/map_invariants.h"
#include "map/sample_kernels.h"
#include "map/split_util.h"

namespace hivox {
namespace {

MapParams three_levels(int64_t blocks = 1 << 14) {
  MapParams p;
  p.voxel_size_m = 0.002f;
  p.levels = 3;
  p.max_blocks = blocks;
  p.buckets_per_level = 1 << 10;  // small tables: chains and excess entries get exercised
  p.excess_per_level = 1 << 13;
  return p;
}

// A smooth, non-linear field to store in voxels: F at world point p (metres).
float field(double x, double y, double z) {
  return static_cast<float>(0.6 * std::sin(7.0 * x + 1.0) * std::cos(5.0 * y) +
                            0.3 * std::sin(9.0 * z));
}

// Fills a block with `field` sampled at its voxel positions, random weights (0 = unobserved now
// and then) and colours.
void fill_block(VoxelBlockMap& map, const BlockRef& b, std::mt19937& rng) {
  const float s = map.params().voxel_size_at(b.level);
  std::uniform_int_distribution<int> w(0, 40), col(0, 255);
  TsdfVoxel* v = MapAccess::tsdf(map, b.ptr);
  ColorVoxel* c = MapAccess::color(map, b.ptr);
  for (int i = 0; i < kBlockVoxels; ++i) {
    const Vec3i q = voxel_coords(i);
    const double x = (8 * b.pos.x + q.x) * s, y = (8 * b.pos.y + q.y) * s,
                 z = (8 * b.pos.z + q.z) * s;
    v[i].tsdf = tsdf_from_float(field(x, y, z));
    v[i].weight = static_cast<uint16_t>(w(rng) < 3 ? 0 : 1 + w(rng));
    c[i] = {static_cast<uint8_t>(col(rng)), static_cast<uint8_t>(col(rng)),
            static_cast<uint8_t>(col(rng)), static_cast<uint8_t>(v[i].weight ? 1 + w(rng) : 0)};
  }
  MapAccess::refresh_surface(map, b.ptr);
}

std::vector<BlockRef> allocate_cube(VoxelBlockMap& map, int level, int n, std::mt19937& rng) {
  std::vector<BlockKey> keys;
  for (int x = -n / 2; x < n - n / 2; ++x)
    for (int y = -n / 2; y < n - n / 2; ++y)
      for (int z = 0; z < n; ++z) keys.push_back({{x, y, z}, level});
  std::vector<BlockRef> refs;
  map.insert_blocks(keys, &refs);
  for (const BlockRef& b : refs) fill_block(map, b, rng);
  return refs;
}

// Parent-level voxel at parent voxel coordinate q (may be 8 = the +1 neighbour), as a test-side
// reference: the neighbour's voxel when the neighbour block exists at that level, else none.
std::optional<TsdfVoxel> parent_voxel(const VoxelBlockMap& map, const BlockRef& parent,
                                      const Vec3i& q) {
  return map.voxel(parent.level,
                   {8 * parent.pos.x + q.x, 8 * parent.pos.y + q.y, 8 * parent.pos.z + q.z});
}

// A value and its weight.
using Sample = std::pair<float, float>;

// A voxel's value and weight, or nothing when it is missing or unobserved.
std::optional<Sample> observed(const std::optional<TsdfVoxel>& v) {
  if (!v || v->weight == 0) return std::nullopt;
  return Sample{tsdf_to_float(v->tsdf), static_cast<float>(v->weight)};
}

// The trilinear value and weight at lattice point `c` of a level from the samples `at(q)` of the
// next coarser level (at c / 2: on its lattice, or halfway between its points along some axes),
// or nothing where one it takes is.
template <typename At>
std::optional<Sample> halfway(const Vec3i& c, const At& at) {
  float f = 0, w = 0;
  for (int k = 0; k < 8; ++k) {
    const int ox = k & 1, oy = (k >> 1) & 1, oz = k >> 2;
    if ((ox && !(c.x & 1)) || (oy && !(c.y & 1)) || (oz && !(c.z & 1))) continue;
    const float a =
        ((c.x & 1) ? 0.5f : 1.0f) * ((c.y & 1) ? 0.5f : 1.0f) * ((c.z & 1) ? 0.5f : 1.0f);
    const std::optional<Sample> v = at(Vec3i{(c.x >> 1) + ox, (c.y >> 1) + oy, (c.z >> 1) + oz});
    if (!v) return std::nullopt;
    f += a * v->first;
    w += a * v->second;
  }
  return Sample{f, w};
}

// The child voxels a split of `parent` should give, computed independently from the voxels of
// its level in `map` as they are now: at global child voxel coordinates, the trilinear value and
// weight, or nothing (unobserved) where a voxel the interpolation takes is unobserved or missing.
// With `coarser`, a voxel missing at the parent's level is interpolated at the same point from
// the next coarser level's voxels where that stores them.
using ChildValues = std::map<std::tuple<int, int, int>, std::optional<Sample>>;
ChildValues expected_children(const VoxelBlockMap& map, const BlockRef& parent,
                              bool coarser = false) {
  const auto at_parent_level = [&](const Vec3i& q) -> std::optional<Sample> {
    const std::optional<TsdfVoxel> v = parent_voxel(map, parent, q);
    if (v || !coarser) return observed(v);
    return halfway(Vec3i{8 * parent.pos.x + q.x, 8 * parent.pos.y + q.y, 8 * parent.pos.z + q.z},
                   [&](const Vec3i& g) { return observed(map.voxel(parent.level + 1, g)); });
  };
  ChildValues expected;
  for (int j = 0; j < 16 * 16 * 16; ++j) {
    const Vec3i c{j % 16, (j / 16) % 16, j / 256};  // child voxel within the parent's extent
    const std::tuple<int, int, int> key{16 * parent.pos.x + c.x, 16 * parent.pos.y + c.y,
                                        16 * parent.pos.z + c.z};
    expected[key] = halfway(c, at_parent_level);
  }
  return expected;
}

// Checks the children of a split (level `parent.level - 1`) against `expected` for weight scale
// 0.5; returns how many observed voxels were checked.
int expect_children(const VoxelBlockMap& map, const BlockRef& parent, const ChildValues& expected) {
  int checked = 0;
  for (const auto& [key, value] : expected) {
    const auto v =
        map.voxel(parent.level - 1, {std::get<0>(key), std::get<1>(key), std::get<2>(key)});
    EXPECT_TRUE(v.has_value());
    if (!v) continue;
    if (!value) {
      EXPECT_EQ(v->weight, 0) << "a voxel next to an unobserved or missing one stays unobserved";
      continue;
    }
    EXPECT_NEAR(tsdf_to_float(v->tsdf), value->first, 1.0f / 32767) << "exact interpolation";
    EXPECT_NEAR(v->weight, std::max(1.0f, std::round(0.5f * value->second)), 0.5f);
    ++checked;
  }
  return checked;
}

TEST(Split, ChildrenAreTheParentInterpolated) {
  std::mt19937 rng(1);
  VoxelBlockMap map(three_levels());
  const auto blocks = allocate_cube(map, 1, 3, rng);
  const BlockRef parent = blocks[13];  // the middle block: all +x/+y/+z neighbours exist
  // Expected child values, computed before the split from the parent and its neighbours.
  const ChildValues expected = expected_children(map, parent);
  int unobserved = 0;
  for (const auto& [key, value] : expected) unobserved += !value;
  EXPECT_GT(unobserved, 100);  // the fill leaves some parent voxels unobserved
  const SplitMergeResult r = split_blocks(map, std::span(&parent, 1), 0.5f);
  ASSERT_EQ(r.done, 1);
  EXPECT_EQ(map.find(1, parent.pos)->ptr, kPtrSplit);
  test::expect_map_consistent(map);
  EXPECT_GT(expect_children(map, parent, expected), 2500);
}

TEST(Split, NoValueIsExtrapolatedTowardsAMissingNeighbour) {
  std::mt19937 rng(3);
  VoxelBlockMap map(three_levels());
  const auto blocks = allocate_cube(map, 1, 1, rng);  // one block, no neighbours
  const BlockRef parent = blocks[0];
  TsdfVoxel* v = MapAccess::tsdf(map, parent.ptr);
  for (int i = 0; i < kBlockVoxels; ++i) v[i].weight = 10;  // all observed
  ASSERT_EQ(split_blocks(map, std::span(&parent, 1), 0.5f).done, 1);
  // Every child voxel inside the parent's voxels is observed; the last half voxel towards +x,
  // +y and +z (child coordinate 15), where the neighbour would be, is not.
  int observed = 0;
  for (int j = 0; j < 16 * 16 * 16; ++j) {
    const Vec3i c{j % 16, (j / 16) % 16, j / 256};
    const auto child =
        map.voxel(0, {16 * parent.pos.x + c.x, 16 * parent.pos.y + c.y, 16 * parent.pos.z + c.z});
    ASSERT_TRUE(child.has_value());
    const bool border = c.x == 15 || c.y == 15 || c.z == 15;
    EXPECT_EQ(child->weight > 0, !border) << c.x << " " << c.y << " " << c.z;
    observed += child->weight > 0;
  }
  EXPECT_EQ(observed, 15 * 15 * 15);
}

TEST(Split, ABorderInterpolatesTowardsASplitNeighboursChildren) {
  std::mt19937 rng(4);
  VoxelBlockMap map(three_levels());
  std::vector<BlockRef> refs;
  map.insert_blocks(std::vector<BlockKey>{{{0, 0, 0}, 1}, {{1, 0, 0}, 1}}, &refs);
  for (const BlockRef& b : refs) fill_block(map, b, rng);
  const BlockRef a = refs[0], b = refs[1];
  // a's reference values, with b's voxels as they are before b splits (a split copies a parent
  // voxel exactly to the child voxel at the same point, so b's children hold them after).
  const ChildValues expected = expected_children(map, a);
  ASSERT_EQ(split_blocks(map, std::span(&b, 1), 1.0f).done, 1);  // weights kept
  ASSERT_FALSE(map.voxel(1, {8, 0, 0}).has_value());             // b is at level 0 now
  ASSERT_EQ(split_blocks(map, std::span(&a, 1), 0.5f).done, 1);
  test::expect_map_consistent(map);
  // The +x border of a's children (child x = 15) interpolates towards b's voxel x = 0, read
  // from b's children; without b it would stay unobserved.
  int border = 0;
  for (const auto& [key, value] : expected) border += std::get<0>(key) == 15 && value.has_value();
  EXPECT_GT(border, 30);
  EXPECT_GT(expect_children(map, a, expected), 2000);
}

TEST(Split, ABorderInterpolatesTowardsACoarserNeighboursVoxels) {
  std::mt19937 rng(5);
  VoxelBlockMap map(three_levels());
  // Two blocks of the coarsest level side by side along x; the first split to level 1, then its
  // child (1, 0, 0), whose +x neighbour's region (level 1 block (2, 0, 0)) is stored at level 2.
  std::vector<BlockRef> refs;
  map.insert_blocks(std::vector<BlockKey>{{{0, 0, 0}, 2}, {{1, 0, 0}, 2}}, &refs);
  for (const BlockRef& b : refs) {
    fill_block(map, b, rng);
    TsdfVoxel* v = MapAccess::tsdf(map, b.ptr);
    for (int i = 0; i < kBlockVoxels; ++i) v[i].weight = 12;  // all observed
  }
  ASSERT_EQ(split_blocks(map, std::span(&refs[0], 1), 1.0f).done, 1);
  const std::optional<BlockRef> parent = map.find(1, {1, 0, 0});
  ASSERT_TRUE(parent.has_value());
  ASSERT_FALSE(map.find(1, {2, 0, 0}).has_value());
  const ChildValues expected = expected_children(map, *parent, true);
  ASSERT_EQ(split_blocks(map, std::span(&*parent, 1), 0.5f).done, 1);
  test::expect_map_consistent(map);
  // The +x border of the children (child x = 15, halfway to the coarse region) is observed and
  // interpolates towards the coarser level's voxels (without them it stayed unobserved: a sliver
  // between the two levels).
  int border = 0;
  for (const auto& [key, value] : expected) border += std::get<0>(key) == 31 && value.has_value();
  EXPECT_EQ(border, 16 * 16);
  EXPECT_EQ(expect_children(map, *parent, expected), 16 * 16 * 16);
}

TEST(SplitMerge, RoundTripReproducesTheParent) {
  std::mt19937 rng(2);
  VoxelBlockMap map(three_levels());
  const auto blocks = allocate_cube(map, 2, 2, rng);
  std::vector<std::vector<TsdfVoxel>> before;
  for (const BlockRef& b : blocks)
    before.emplace_back(map.block_tsdf(b.ptr), map.block_tsdf(b.ptr) + kBlockVoxels);
  ASSERT_EQ(split_blocks(map, blocks, 1.0f).done, static_cast<int64_t>(blocks.size()));
  EXPECT_EQ(map.blocks_per_level(), (std::vector<int64_t>{0, 64, 0}));
  std::vector<BlockKey> parents;
  for (const BlockRef& b : blocks) parents.push_back({b.pos, b.level});
  ASSERT_EQ(merge_blocks(map, parents).done, static_cast<int64_t>(blocks.size()));
  EXPECT_EQ(map.blocks_per_level(), (std::vector<int64_t>{0, 0, 8}));
  test::expect_map_consistent(map);
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    const auto now = map.find(2, blocks[i].pos);
    ASSERT_TRUE(now && now->ptr >= 0);
    const TsdfVoxel* v = map.block_tsdf(now->ptr);
    for (int k = 0; k < kBlockVoxels; ++k) {
      ASSERT_EQ(v[k].weight, before[i][k].weight) << "weight scale 1: exact";
      if (before[i][k].weight) {
        ASSERT_EQ(v[k].tsdf, before[i][k].tsdf) << "voxel " << k;
      }
    }
  }
}

// The hierarchy is consistent and covers the volume it did (in finest-level blocks).
void expect_covers(const VoxelBlockMap& map, int64_t covered_finest_blocks) {
  int64_t covered = -1;
  test::expect_hierarchy_consistent(map, &covered);
  EXPECT_EQ(covered, covered_finest_blocks) << "covered volume changed";
}

// Random split and merge sequence; returns a fingerprint of the final map.
std::map<std::tuple<int, int, int, int>, std::vector<int16_t>> random_sequence(unsigned seed,
                                                                               int threads) {
  set_thread_count(threads);
  std::mt19937 rng(seed);
  VoxelBlockMap map(three_levels(1500));  // small pool: splits must wait now and then
  std::mt19937 fill_rng(seed + 100);
  allocate_cube(map, 2, 4, fill_rng);
  const int64_t covered = 64 * 64;
  int64_t waited = 0;
  for (int round = 0; round < 12; ++round) {
    // Choices in a fixed order (pool and entry positions differ with the thread count).
    auto blocks = map.allocated_blocks();
    std::sort(blocks.begin(), blocks.end(), [](const BlockRef& a, const BlockRef& b) {
      return BlockKey{a.pos, a.level} < BlockKey{b.pos, b.level};
    });
    std::vector<BlockRef> split;
    for (const BlockRef& b : blocks)
      if (b.level > 0 && rng() % 3 == 0) split.push_back(b);
    waited += split_blocks(map, split, 0.5f).waiting;
    expect_covers(map, covered);
    std::vector<BlockKey> split_entries, merge;
    for (int l = 1; l < 3; ++l)
      for (int32_t e = 0; e < map.view().level[l].entry_count; ++e) {
        const HashEntry& h = map.view().level[l].entries[e];
        if (h.ptr == kPtrSplit) split_entries.push_back({h.pos, l});
      }
    std::sort(split_entries.begin(), split_entries.end());
    for (const BlockKey& k : split_entries)
      if (rng() % 2 == 0) merge.push_back(k);
    merge_blocks(map, merge);
    expect_covers(map, covered);
  }
  EXPECT_GT(waited, 0) << "the pool never ran out: the waiting path was not exercised";
  std::map<std::tuple<int, int, int, int>, std::vector<int16_t>> out;
  for (const BlockRef& b : map.allocated_blocks()) {
    std::vector<int16_t> t(kBlockVoxels);
    for (int i = 0; i < kBlockVoxels; ++i) t[i] = map.block_tsdf(b.ptr)[i].tsdf;
    out[{b.level, b.pos.x, b.pos.y, b.pos.z}] = t;
  }
  return out;
}

TEST(SplitMerge, RandomSequencesKeepTheHierarchyConsistent) {
  for (unsigned seed : {3u, 4u}) random_sequence(seed, 2);
  set_thread_count(0);
}

TEST(SplitMerge, ConcurrentEqualsSerial) {
  const auto serial = random_sequence(5, 1);
  const auto parallel = random_sequence(5, 4);
  set_thread_count(0);
  EXPECT_EQ(serial.size(), parallel.size());
  EXPECT_TRUE(serial == parallel);
}

TEST(SplitMerge, InvalidRequestsAreCountedNotApplied) {
  std::mt19937 rng(6);
  VoxelBlockMap map(three_levels());
  const auto blocks = allocate_cube(map, 0, 1, rng);  // finest level: cannot split
  EXPECT_EQ(split_blocks(map, blocks).invalid, 1);
  const std::vector<BlockKey> not_split = {{{0, 0, 0}, 1}};
  EXPECT_EQ(merge_blocks(map, not_split).invalid, 1);
  test::expect_map_consistent(map);
}

// Where the block storing a point lies, found as the hierarchy defines it: from the coarsest
// level down through Split entries (the level and block where that ends, and the ptr there).
struct Located {
  int32_t ptr = kPtrEmpty;
  int level = -1;
  Vec3i pos;
};
Located descend(const VoxelBlockMap& map, const Vec3f& p) {
  Located r;
  for (int l = map.levels() - 1; l >= 0; --l) {
    r.level = l;
    r.pos = block_of_point(map.view().level[l], p);
    const std::optional<BlockRef> e = map.find(l, r.pos);
    r.ptr = e ? e->ptr : kPtrEmpty;
    if (r.ptr != kPtrSplit) break;
  }
  return r;
}

TEST(LocateBlock, EndsWhereTheDescentFromTheCoarsestEndsFromAnyStart) {
  // A cube of coarse blocks, some split once or twice, in empty space; points inside and around.
  std::mt19937 rng(8);
  VoxelBlockMap map(three_levels());
  allocate_cube(map, 2, 4, rng);
  test::split_down(map, 2, [&](const BlockRef&) { return rng() % 3 == 0; });
  test::expect_hierarchy_consistent(map);
  const std::vector<int64_t> per_level = map.blocks_per_level();
  ASSERT_GT(per_level[0], 0);
  ASSERT_GT(per_level[1], 0);
  ASSERT_GT(per_level[2], 0);
  const MapView view = map.view();
  const float side_m = 4 * view.level[2].block_size_m;
  std::uniform_real_distribution<float> u(-0.75f * side_m, 0.75f * side_m), uz(-0.25f, 1.25f);
  int at_level[3] = {}, empty = 0;
  for (int i = 0; i < 20000; ++i) {
    const Vec3f p{u(rng), u(rng), uz(rng) * side_m};
    const Located want = descend(map, p);
    (want.ptr >= 0 ? at_level[want.level] : empty) += 1;
    for (int start : {-1, 0, 1, 2, 3}) {
      auto cache = std::make_unique<kernels::BlockLookupCache>();
      int level = -9;
      Vec3i pos;
      const int32_t ptr = kernels::locate_block(view, *cache, p, &level, &pos, start);
      ASSERT_EQ(ptr, want.ptr) << "start " << start;
      ASSERT_EQ(level, want.level) << "start " << start;
      ASSERT_TRUE(pos == want.pos) << "start " << start;
      // What the start saves: from the level storing the point, one look-up.
      if (want.ptr >= 0 && start == want.level) {
        EXPECT_EQ(cache->table_lookups, 1);
      }
    }
  }
  EXPECT_GT(at_level[0], 300);
  EXPECT_GT(at_level[1], 1000);
  EXPECT_GT(at_level[2], 1000);
  EXPECT_GT(empty, 1000);
}

TEST(NeighbourBlocks, LooksUpOnlyTheBlocksOfTheSpansAskedFor) {
  // Blocks of one level with gaps: some of the 2x2x2 around a block are absent.
  std::mt19937 rng(9);
  VoxelBlockMap map(three_levels());
  std::vector<BlockKey> keys;
  for (int x = 0; x < 6; ++x)
    for (int y = 0; y < 6; ++y)
      for (int z = 0; z < 6; ++z)
        if (rng() % 3 != 0) keys.push_back({{x, y, z}, 1});
  map.insert_blocks(keys);
  const MapView view = map.view();
  std::uniform_int_distribution<int> pos(0, 4), bit(0, 1);
  for (int trial = 0; trial < 500; ++trial) {
    const Vec3i b{pos(rng), pos(rng), pos(rng)};
    int32_t all[8];  // the 2x2x2 blocks from b up, slot d at b + (d & 1, d >> 1 & 1, d >> 2)
    for (int d = 0; d < 8; ++d)
      all[d] = find_block_ptr(view.level[1], {b.x + (d & 1), b.y + ((d >> 1) & 1), b.z + (d >> 2)});
    auto cache = std::make_unique<kernels::BlockLookupCache>();
    kernels::NeighbourBlocks nb;
    bool asked[8] = {};
    for (int call = 0; call < 3; ++call) {
      const Vec3i span{bit(rng), bit(rng), bit(rng)};
      const int32_t* got = nb.get(view, *cache, 1, b, span);
      int64_t distinct = 0;
      for (int d = 0; d < 8; ++d) {
        const bool in_span = (d & 1) <= span.x && ((d >> 1) & 1) <= span.y && (d >> 2) <= span.z;
        asked[d] = asked[d] || in_span;
        distinct += asked[d];
        if (asked[d]) {
          EXPECT_EQ(got[d], all[d]) << "slot " << d;
        } else {
          EXPECT_EQ(got[d], kernels::NeighbourBlocks::kNotLookedUp) << "slot " << d;
        }
      }
      EXPECT_EQ(cache->table_lookups, distinct) << "each block of the spans once, no other";
    }
  }
}

}  // namespace
}  // namespace hivox

#pragma once
// Structural invariants of a VoxelBlockMap, checked by walking every chain.

#include <gtest/gtest.h>

#include <set>
#include <tuple>
#include <vector>

#include "hivox/map/voxel_block_map.h"
#include "map/map_access.h"

namespace hivox::test {

/// The surface summary of a block recomputed from its voxels cell by cell: octant o holds the
/// cells whose lowest voxel has coordinates in [4 (o & 1), +3] along x (likewise y with o & 2,
/// z with o & 4); a cell's corners are its lowest voxel plus 0 or 1 per axis, within the block.
inline BlockSurface surface_from_voxels(const TsdfVoxel* voxels) {
  BlockSurface s;
  for (int o = 0; o < 8; ++o) {
    const Vec3i lo{4 * (o & 1), 2 * (o & 2), (o & 4)};
    for (int z = lo.z; z < lo.z + 4; ++z)
      for (int y = lo.y; y < lo.y + 4; ++y)
        for (int x = lo.x; x < lo.x + 4; ++x)
          for (int c = 0; c < 8; ++c) {
            const int cx = x + (c & 1), cy = y + ((c >> 1) & 1), cz = z + (c >> 2);
            if (cx > 7 || cy > 7 || cz > 7) continue;
            const TsdfVoxel& v = voxels[voxel_index(cx, cy, cz)];
            if (v.weight == 0) continue;
            s.observed = static_cast<uint8_t>(s.observed | (1u << o));
            if (v.tsdf <= 0) s.surface = static_cast<uint8_t>(s.surface | (1u << o));
          }
  }
  return s;
}

/// Checks: every chain is acyclic and entries are reached from exactly one bucket; every used
/// entry hashes to the bucket it hangs from; no key twice per level; every pool block is either
/// free or owned by exactly one Allocated entry, and its surface summary is its voxels';
/// per-level counters match the tables.
inline void expect_map_consistent(const VoxelBlockMap& map) {
  const MapView v = map.view();
  const MutableMapView storage = MapAccess::storage(map);
  std::vector<int> owner(static_cast<std::size_t>(v.block_capacity), 0);
  for (int l = 0; l < v.levels; ++l) {
    const LevelView& lv = v.level[l];
    std::vector<uint8_t> seen(static_cast<std::size_t>(lv.entry_count), 0);
    std::set<std::tuple<int, int, int>> keys;
    int64_t allocated = 0;
    const int32_t buckets = static_cast<int32_t>(lv.bucket_mask) + 1;
    for (int32_t b = 0; b < buckets; ++b) {
      for (int32_t i = b, steps = 0; i != kNoEntry; i = lv.entries[i].next, ++steps) {
        ASSERT_LT(steps, lv.entry_count) << "cycle in chain of bucket " << b;
        ASSERT_FALSE(seen[i]) << "entry " << i << " reachable twice (level " << l << ")";
        seen[i] = 1;
        const HashEntry& e = lv.entries[i];
        ASSERT_NE(entry_state(e.ptr), EntryState::Reserved);
        if (e.ptr == kPtrEmpty) continue;
        EXPECT_EQ(block_hash(e.pos, lv.bucket_mask), static_cast<uint32_t>(b));
        EXPECT_TRUE(keys.emplace(e.pos.x, e.pos.y, e.pos.z).second)
            << "duplicate key at level " << l;
        if (e.ptr >= 0) {
          ASSERT_LT(e.ptr, v.block_capacity);
          ++owner[e.ptr];
          ++allocated;
          const BlockMeta& m = map.block_meta(e.ptr);
          EXPECT_EQ(m.level, l);
          EXPECT_EQ(m.pos, e.pos);
          EXPECT_EQ(m.entry, i);
          EXPECT_LT(e.ptr, map.block_high_water());
          const BlockSurface s = surface_from_voxels(map.block_tsdf(e.ptr));
          EXPECT_EQ(m.surface.observed, s.observed) << "block " << e.ptr;
          EXPECT_EQ(m.surface.surface, s.surface) << "block " << e.ptr;
        }
      }
    }
    EXPECT_EQ(allocated, map.blocks_per_level()[l]) << "level " << l << " counter";
    // Excess entries not linked from any chain must be on the free list.
    std::vector<uint8_t> free_excess(static_cast<std::size_t>(lv.entry_count), 0);
    const FreeListView& excess = storage.level[l].excess;
    for (int32_t k = 0; k < *excess.count; ++k) {
      const int32_t e = excess.items[k];
      ASSERT_GE(e, buckets);
      ASSERT_FALSE(free_excess[e]) << "excess entry " << e << " free twice";
      free_excess[e] = 1;
      EXPECT_FALSE(seen[e]) << "excess entry " << e << " is both free and linked";
    }
    for (int32_t e = buckets; e < lv.entry_count; ++e)
      EXPECT_TRUE(seen[e] || free_excess[e]) << "excess entry " << e << " leaked";
  }
  for (int32_t k = 0; k < *storage.blocks.count; ++k) {
    const int32_t b = storage.blocks.items[k];
    ASSERT_GE(b, 0);
    ASSERT_LT(b, v.block_capacity);
    ++owner[b];
    EXPECT_EQ(map.block_meta(b).level, -1) << "free pool block " << b << " still has a level";
  }
  for (int32_t b = 0; b < v.block_capacity; ++b)
    ASSERT_EQ(owner[b], 1) << "pool block " << b << " is owned " << owner[b] << " times";
}

/// expect_map_consistent, and the hierarchy's own invariants: every allocated block's ancestors
/// are Split entries, no region is stored at two levels (an allocated block has no children),
/// and every Split entry has all 8 children. `covered_finest_blocks` (optional) receives the
/// volume the map covers, in blocks of the finest level.
inline void expect_hierarchy_consistent(const VoxelBlockMap& map,
                                        int64_t* covered_finest_blocks = nullptr) {
  expect_map_consistent(map);
  const MapView v = map.view();
  auto child = [](const Vec3i& p, int c) {
    return Vec3i{2 * p.x + (c & 1), 2 * p.y + ((c >> 1) & 1), 2 * p.z + (c >> 2)};
  };
  int64_t covered = 0;
  for (const BlockRef& b : map.allocated_blocks()) {
    covered += int64_t{1} << (3 * b.level);
    Vec3i p = b.pos;
    for (int l = b.level + 1; l < v.levels; ++l) {
      p = {p.x >> 1, p.y >> 1, p.z >> 1};
      ASSERT_EQ(find_block_ptr(v.level[l], p), kPtrSplit)
          << "the level-" << l << " ancestor of level-" << b.level << " block (" << b.pos.x << ", "
          << b.pos.y << ", " << b.pos.z << ") is not a Split entry";
    }
    if (b.level > 0) {
      for (int c = 0; c < 8; ++c)
        ASSERT_EQ(find_block_ptr(v.level[b.level - 1], child(b.pos, c)), kPtrEmpty)
            << "region stored at two levels: level-" << b.level << " block (" << b.pos.x << ", "
            << b.pos.y << ", " << b.pos.z << ") has a child";
    }
  }
  for (int l = 1; l < v.levels; ++l)
    for (int32_t e = 0; e < v.level[l].entry_count; ++e) {
      const HashEntry& h = v.level[l].entries[e];
      if (h.ptr != kPtrSplit) continue;
      for (int c = 0; c < 8; ++c)
        ASSERT_NE(find_block_ptr(v.level[l - 1], child(h.pos, c)), kPtrEmpty)
            << "the Split entry at level " << l << " (" << h.pos.x << ", " << h.pos.y << ", "
            << h.pos.z << ") lacks child " << c << " (a hole)";
    }
  if (covered_finest_blocks != nullptr) *covered_finest_blocks = covered;
}

}  // namespace hivox::test

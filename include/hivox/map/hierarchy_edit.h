#pragma once
/// @file
/// Moving parts of the map between levels: a block splits into its 8 children one level finer,
/// 8 sibling leaves merge back into their parent. The map keeps the hierarchy's invariants here
/// (no region at two levels, no hole, the pool and the tables' counters); what to split or merge
/// is decided elsewhere (the refinement's criterion). Both edits are parallel, lock-free and give
/// the same map whatever the thread count.

#include <cstdint>
#include <span>

#include "hivox/core/hd.h"
#include "hivox/map/voxel_block_map.h"

namespace hivox {

/// Children per block: a block at level l + 1 covers 2x2x2 blocks of level l.
inline constexpr int kBlockChildren = 8;

/// Block coordinates of child `c` (offset (c & 1, (c >> 1) & 1, c >> 2)) of block `parent`.
HIVOX_HD inline Vec3i child_block_pos(const Vec3i& parent, int c) {
  return {2 * parent.x + (c & 1), 2 * parent.y + ((c >> 1) & 1), 2 * parent.z + (c >> 2)};
}

/// Block coordinates of the parent of block `child` (one level coarser).
HIVOX_HD inline Vec3i parent_block_pos(const Vec3i& child) {
  return {child.x >> 1, child.y >> 1, child.z >> 1};  // arithmetic shift: floor division
}

struct SplitMergeResult {
  int64_t done = 0;     ///< blocks split (or parents merged)
  int64_t waiting = 0;  ///< wanted, but the pool or an overflow list lacked room: retried later
  int64_t invalid = 0;  ///< not in a state that allows it (e.g. no longer allocated)
};

/// Splits each allocated block of `blocks` above the finest level into its 8 children one level
/// finer, filled by trilinear interpolation of the parent (weights times `weight_scale`); the
/// parent's entry becomes Split and its block returns to the pool. A full pool makes splits
/// wait (counted), never lose data: either all 8 children exist or the parent stays. The same
/// subset waits whatever the thread count.
SplitMergeResult split_blocks(VoxelBlockMap& map, std::span<const BlockRef> blocks,
                              float weight_scale = 0.5f);

/// Merges each Split parent of `parents` whose 8 children are allocated leaves: the parent gets a
/// fresh block filled by subsampling the children, the children's entries become Empty (chains
/// shortened at their tail only) and their blocks return to the pool.
SplitMergeResult merge_blocks(VoxelBlockMap& map, std::span<const BlockKey> parents);

}  // namespace hivox

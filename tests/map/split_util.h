#pragma once
// Building a hierarchy for tests: splitting chosen blocks down through the map's own split.

#include <gtest/gtest.h>

#include <functional>
#include <vector>

#include "hivox/map/hierarchy_edit.h"
#include "hivox/map/voxel_block_map.h"

namespace hivox::test {

/// Splits the blocks that `pick` accepts, level by level from `level` down to level 1 (children
/// made at one level are offered to `pick` at the next), through `split_blocks` with
/// `weight_scale`, so the hierarchy is consistent. Every chosen split must succeed.
inline void split_down(VoxelBlockMap& map, int level,
                       const std::function<bool(const BlockRef&)>& pick,
                       float weight_scale = 0.5f) {
  for (int l = level; l > 0; --l) {
    std::vector<BlockRef> chosen;
    for (const BlockRef& b : map.allocated_blocks())
      if (b.level == l && pick(b)) chosen.push_back(b);
    EXPECT_EQ(split_blocks(map, chosen, weight_scale).done, static_cast<int64_t>(chosen.size()))
        << "level " << l;
  }
}

}  // namespace hivox::test

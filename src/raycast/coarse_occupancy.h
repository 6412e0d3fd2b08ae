#pragma once
// A coarse occupancy grid for marching rays across empty space: written once for the CPU and
// CUDA drivers (the grid's view), filled on the CPU from the map (build_coarse_occupancy).

#include <cstdint>
#include <vector>

#include "hivox/core/atomic.h"
#include "hivox/core/hd.h"
#include "hivox/core/math.h"

namespace hivox {
class VoxelBlockMap;
}

namespace hivox::kernels {

/// Which cubes of space ("super-blocks", each `kSuperBlockSide` blocks of the coarsest level on a
/// side) hold a block of any level: a march crosses an empty one in one step instead of block
/// by block (rays that miss, or start far in front of their surface, cross ~10 unallocated
/// blocks). A view of the grid build_coarse_occupancy fills from the map before casting; `cells`
/// null: no grid, every super-block may hold blocks.
struct CoarseOccupancy {
  static constexpr int kSuperBlockShift = 2;
  static constexpr int kSuperBlockSide = 1 << kSuperBlockShift;
  int32_t* cells = nullptr;  ///< 1 where a block lies, x fastest; outside [lo, lo + dims): none
  Vec3i lo, dims;
  float side_m = 0, inv_side_m = 0;

  /// The super-block of block `pos` of `level` in a map of `levels` levels.
  HIVOX_HD static Vec3i super_block_of(const Vec3i& pos, int level, int levels) {
    // floor(pos / (kSuperBlockSide << (levels - 1 - level))): a shift, which rounds towards
    // -infinity (a division by a divisor not known at compile time costs ~10x the loop).
    const int shift = kSuperBlockShift + (levels - 1 - level);
    return {pos.x >> shift, pos.y >> shift, pos.z >> shift};
  }
  HIVOX_HD Vec3i cell_of(const Vec3f& p_w) const { return floor_to_int(p_w * inv_side_m); }
  HIVOX_HD bool empty(const Vec3i& c) const {
    if (cells == nullptr) return false;
    const Vec3i r{c.x - lo.x, c.y - lo.y, c.z - lo.z};
    if (r.x < 0 || r.y < 0 || r.z < 0 || r.x >= dims.x || r.y >= dims.y || r.z >= dims.z)
      return true;
    return cells[(static_cast<int64_t>(r.z) * dims.y + r.y) * dims.x + r.x] == 0;
  }
  /// Marks super-block `c` (inside the grid) as holding a block; threads may mark concurrently.
  HIVOX_HD void mark(const Vec3i& c) const {
    atomic_store(
        &cells[(static_cast<int64_t>(c.z - lo.z) * dims.y + (c.y - lo.y)) * dims.x + (c.x - lo.x)],
        1);
  }
};

/// Fills `cells` with the super-blocks of `map` that hold a block of any level and returns the
/// view of it (valid while `cells` and the map's layout do not change). No grid (`cells` null in
/// the view) when the map has no blocks or its blocks span more than 2^22 super-blocks (a map
/// spread over a huge box: rays then cross unallocated space block by block).
CoarseOccupancy build_coarse_occupancy(const VoxelBlockMap& map, std::vector<int32_t>* cells);

}  // namespace hivox::kernels

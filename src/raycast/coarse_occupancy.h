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
struct BlockMeta;
}  // namespace hivox

namespace hivox::kernels {

/// The box [lo, hi] of super-blocks (CoarseOccupancy's cells) that hold blocks; empty while
/// lo > hi. A split's children and a merge's parent lie in the super-block of the blocks they
/// replace, so only insertions grow it.
struct SuperBlockBounds {
  Vec3i lo{INT32_MAX, INT32_MAX, INT32_MAX}, hi{INT32_MIN, INT32_MIN, INT32_MIN};

  HIVOX_HD bool empty() const { return lo.x > hi.x; }
  HIVOX_HD void add(const Vec3i& c) {
    for (int a = 0; a < 3; ++a) {
      lo[a] = c[a] < lo[a] ? c[a] : lo[a];
      hi[a] = c[a] > hi[a] ? c[a] : hi[a];
    }
  }
  /// add(c) where threads may add concurrently (an atomic only where `c` lies outside).
  HIVOX_HD void add_atomic(const Vec3i& c) {
    for (int a = 0; a < 3; ++a) {
      if (c[a] < atomic_load(&lo[a])) atomic_min(&lo[a], c[a]);
      if (c[a] > atomic_load(&hi[a])) atomic_max(&hi[a], c[a]);
    }
  }
  void merge(const SuperBlockBounds& o) {
    if (o.empty()) return;
    add(o.lo);
    add(o.hi);
  }
};

/// Which cubes of space ("super-blocks", each `kSuperBlockSide` blocks of the coarsest level on a
/// side) hold a block of any level: a march crosses an empty one in one step instead of block
/// by block (rays that miss, or start far in front of their surface, cross ~10 unallocated
/// blocks). A view of the grid build_coarse_occupancy fills from the map before casting; `cells`
/// null: no grid, every super-block may hold blocks.
struct CoarseOccupancy {
  static constexpr int kSuperBlockShift = 2;
  static constexpr int kSuperBlockSide = 1 << kSuperBlockShift;
  /// Beyond this many cells there is no grid (a map spread over a huge box: rays then cross
  /// unallocated space block by block).
  static constexpr int64_t kMaxCells = int64_t{1} << 22;
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
  /// The grid over `bounds` for a map whose coarsest blocks are `coarsest_block_m` on a side,
  /// its cells not yet set (`cells` null); no dims where `bounds` is empty.
  static CoarseOccupancy covering(const SuperBlockBounds& bounds, float coarsest_block_m) {
    CoarseOccupancy grid;
    if (bounds.empty()) return grid;
    grid.lo = bounds.lo;
    grid.dims = {bounds.hi.x - bounds.lo.x + 1, bounds.hi.y - bounds.lo.y + 1,
                 bounds.hi.z - bounds.lo.z + 1};
    grid.side_m = kSuperBlockSide * coarsest_block_m;
    grid.inv_side_m = 1.0f / grid.side_m;
    return grid;
  }
  /// How many cells the grid spans (0 when it has no dims).
  int64_t cell_count() const { return static_cast<int64_t>(dims.x) * dims.y * dims.z; }
  HIVOX_HD Vec3i cell_of(const Vec3f& p_w) const { return floor_to_int(p_w * inv_side_m); }
  HIVOX_HD bool covers(const Vec3i& c) const {
    const Vec3i r{c.x - lo.x, c.y - lo.y, c.z - lo.z};
    return r.x >= 0 && r.y >= 0 && r.z >= 0 && r.x < dims.x && r.y < dims.y && r.z < dims.z;
  }
  /// Cell `c`'s (inside the grid) place in `cells`.
  HIVOX_HD int64_t index_of(const Vec3i& c) const {
    return (static_cast<int64_t>(c.z - lo.z) * dims.y + (c.y - lo.y)) * dims.x + (c.x - lo.x);
  }
  HIVOX_HD bool empty(const Vec3i& c) const {
    if (cells == nullptr) return false;
    return !covers(c) || cells[index_of(c)] == 0;
  }
  /// Marks super-block `c` (inside the grid) as holding a block; threads may mark concurrently.
  HIVOX_HD void mark(const Vec3i& c) const { atomic_store(&cells[index_of(c)], 1); }
};

/// The super-blocks that hold the blocks below `high_water` of `map` (levels `levels`).
SuperBlockBounds super_block_bounds(const BlockMeta* meta, int32_t high_water, int levels);

/// Fills `cells` with the super-blocks of `map` that hold a block of any level and returns the
/// view of it (valid while `cells` and the map's layout do not change). No grid (`cells` null in
/// the view) when the map has no blocks or its blocks span more than kMaxCells super-blocks.
CoarseOccupancy build_coarse_occupancy(const VoxelBlockMap& map, std::vector<int32_t>* cells);

}  // namespace hivox::kernels

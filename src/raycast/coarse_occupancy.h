#pragma once
// A coarse occupancy grid for marching rays across space without a surface: written once for the
// CPU and CUDA drivers (the grid's view), filled on the CPU from the map (build_coarse_occupancy).

#include <cstdint>
#include <vector>

#include "hivox/core/hd.h"
#include "hivox/core/math.h"

namespace hivox {
class VoxelBlockMap;
}

namespace hivox::kernels {

/// Where the map may hold a surface: per cube of `kSuperBlockSide`^3 blocks of the coarsest level
/// (a "super-block"), a mask of which of those blocks' cells hold a block, of any level, with an
/// observed voxel at or behind a surface (BlockSurface::surface not 0). Every crossing of the
/// TSDF lies in such a cell or within a voxel of one (a cell of voxels reaching into the next
/// block), so a march crosses an empty super-block in one step and an unmarked cell of a marked
/// one in one step, without a hash look-up: rays that miss, or start far in front of their
/// surface, cross ~10 blocks that are unallocated or hold free space only. A view of the grid
/// build_coarse_occupancy fills from the map before casting; `cells` null: no grid, every cell
/// may hold a surface.
struct CoarseOccupancy {
  static constexpr int kSuperBlockSide = 4;
  uint64_t* cells = nullptr;  ///< per super-block, x fastest; outside [lo, lo + dims): all 0
  Vec3i lo, dims;
  float side_m = 0, inv_side_m = 0;    ///< of a super-block
  float block_m = 0, inv_block_m = 0;  ///< of a block of the coarsest level (a cell)

  /// The block of the coarsest level holding block `pos` of `level` in a map of `levels` levels.
  HIVOX_HD static Vec3i coarse_block_of(const Vec3i& pos, int level, int levels) {
    const int k = 1 << (levels - 1 - level);
    return {floor_div(pos.x, k), floor_div(pos.y, k), floor_div(pos.z, k)};
  }
  /// The super-block of a block of the coarsest level.
  HIVOX_HD static Vec3i super_block_of(const Vec3i& coarse_block) {
    return {floor_div(coarse_block.x, kSuperBlockSide), floor_div(coarse_block.y, kSuperBlockSide),
            floor_div(coarse_block.z, kSuperBlockSide)};
  }
  /// The bit of a block of the coarsest level in its super-block's mask.
  HIVOX_HD static uint64_t bit_of(const Vec3i& coarse_block) {
    constexpr int m = kSuperBlockSide - 1;
    return uint64_t{1} << ((coarse_block.x & m) | (coarse_block.y & m) << 2 |
                           (coarse_block.z & m) << 4);
  }
  /// The block of the coarsest level around point `p_w`.
  HIVOX_HD Vec3i coarse_block_at(const Vec3f& p_w) const { return floor_to_int(p_w * inv_block_m); }
  /// Super-block `c`'s mask (every bit set without a grid).
  HIVOX_HD uint64_t mask(const Vec3i& c) const {
    if (cells == nullptr) return ~uint64_t{0};
    const Vec3i r{c.x - lo.x, c.y - lo.y, c.z - lo.z};
    if (r.x < 0 || r.y < 0 || r.z < 0 || r.x >= dims.x || r.y >= dims.y || r.z >= dims.z) return 0;
    return cells[(static_cast<int64_t>(r.z) * dims.y + r.y) * dims.x + r.x];
  }
  HIVOX_HD bool empty(const Vec3i& c) const { return mask(c) == 0; }
  /// Whether the cell of block `coarse_block` of the coarsest level may hold a surface.
  HIVOX_HD bool may_hold_surface(const Vec3i& coarse_block) const {
    return (mask(super_block_of(coarse_block)) & bit_of(coarse_block)) != 0;
  }
};

/// Fills `cells` with the masks of the blocks of `map` that hold a surface and returns the view of
/// it (valid while `cells` and the map's blocks and their summaries do not change). No grid
/// (`cells` null in the view) when the map has no such block or they span more than 2^22
/// super-blocks (a map spread over a huge box: rays then look up every block they cross).
CoarseOccupancy build_coarse_occupancy(const VoxelBlockMap& map, std::vector<uint64_t>* cells);

}  // namespace hivox::kernels

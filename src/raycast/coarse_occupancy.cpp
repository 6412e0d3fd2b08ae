#include "raycast/coarse_occupancy.h"

#include <algorithm>
#include <climits>

#include "hivox/map/voxel_block_map.h"

namespace hivox::kernels {

CoarseOccupancy build_coarse_occupancy(const VoxelBlockMap& map, std::vector<int32_t>* cells) {
  constexpr int64_t kMaxCells = int64_t{1} << 22;
  const MapView view = map.view();
  const int levels = map.levels();
  const int32_t high_water = map.block_high_water();
  int lo_x = INT_MAX, lo_y = INT_MAX, lo_z = INT_MAX, hi_x = INT_MIN, hi_y = INT_MIN,
      hi_z = INT_MIN;
#pragma omp parallel for schedule(static) reduction(min                 \
                                                    : lo_x, lo_y, lo_z) \
    reduction(max                                                       \
              : hi_x, hi_y, hi_z)
  for (int32_t ptr = 0; ptr < high_water; ++ptr) {
    const BlockMeta& m = view.meta[ptr];
    if (m.level < 0) continue;
    const Vec3i c = CoarseOccupancy::super_block_of(m.pos, m.level, levels);
    lo_x = std::min(lo_x, c.x);
    lo_y = std::min(lo_y, c.y);
    lo_z = std::min(lo_z, c.z);
    hi_x = std::max(hi_x, c.x);
    hi_y = std::max(hi_y, c.y);
    hi_z = std::max(hi_z, c.z);
  }
  CoarseOccupancy grid;
  if (lo_x > hi_x) return grid;  // no blocks
  grid.lo = {lo_x, lo_y, lo_z};
  grid.dims = {hi_x - lo_x + 1, hi_y - lo_y + 1, hi_z - lo_z + 1};
  const int64_t count = static_cast<int64_t>(grid.dims.x) * grid.dims.y * grid.dims.z;
  if (count > kMaxCells) return grid;
  cells->assign(static_cast<std::size_t>(count), 0);
  grid.cells = cells->data();
  grid.side_m = CoarseOccupancy::kSuperBlockSide * view.level[levels - 1].block_size_m;
  grid.inv_side_m = 1.0f / grid.side_m;
#pragma omp parallel for schedule(static)
  for (int32_t ptr = 0; ptr < high_water; ++ptr) {
    const BlockMeta& m = view.meta[ptr];
    if (m.level >= 0) grid.mark(CoarseOccupancy::super_block_of(m.pos, m.level, levels));
  }
  return grid;
}

}  // namespace hivox::kernels

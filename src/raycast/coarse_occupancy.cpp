#include "raycast/coarse_occupancy.h"

#include <algorithm>
#include <climits>
#include <vector>

#include "core/parallel.h"

#include "hivox/map/voxel_block_map.h"

namespace hivox::kernels {

CoarseOccupancy build_coarse_occupancy(const VoxelBlockMap& map, std::vector<int32_t>* cells) {
  constexpr int64_t kMaxCells = int64_t{1} << 22;
  const MapView view = map.view();
  const int levels = map.levels();
  const int32_t high_water = map.block_high_water();
  // The super-blocks' bounds: per thread, then merged.
  struct Bounds {
    Vec3i lo{INT_MAX, INT_MAX, INT_MAX}, hi{INT_MIN, INT_MIN, INT_MIN};
    void add(const Vec3i& c) {
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], c[a]);
        hi[a] = std::max(hi[a], c[a]);
      }
    }
  };
  std::vector<Bounds> partial(static_cast<std::size_t>(thread_count()));
  parallel_team([&](const ThreadTeam& team) {
    Bounds b;
    team.for_each(high_water, [&](int64_t ptr) {
      const BlockMeta& m = view.meta[ptr];
      if (m.level >= 0) b.add(CoarseOccupancy::super_block_of(m.pos, m.level, levels));
    });
    partial[static_cast<std::size_t>(team.index())] = b;
  });
  Bounds all;
  for (const Bounds& b : partial)
    for (int a = 0; a < 3; ++a) {
      all.lo[a] = std::min(all.lo[a], b.lo[a]);
      all.hi[a] = std::max(all.hi[a], b.hi[a]);
    }
  const int lo_x = all.lo.x, lo_y = all.lo.y, lo_z = all.lo.z;
  const int hi_x = all.hi.x, hi_y = all.hi.y, hi_z = all.hi.z;
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
  parallel_for(high_water, [&](int64_t ptr) {
    const BlockMeta& m = view.meta[ptr];
    if (m.level >= 0) grid.mark(CoarseOccupancy::super_block_of(m.pos, m.level, levels));
  });
  return grid;
}

}  // namespace hivox::kernels

#include "raycast/coarse_occupancy.h"

#include <vector>

#include "core/parallel.h"

#include "hivox/map/map_view.h"
#include "hivox/map/voxel_block_map.h"

namespace hivox::kernels {

SuperBlockBounds super_block_bounds(const BlockMeta* meta, int32_t high_water, int levels) {
  // Per thread, then merged.
  std::vector<SuperBlockBounds> partial(static_cast<std::size_t>(thread_count()));
  parallel_team([&](const ThreadTeam& team) {
    SuperBlockBounds b;
    team.for_each(high_water, [&](int64_t ptr) {
      const BlockMeta& m = meta[ptr];
      if (m.level >= 0) b.add(CoarseOccupancy::super_block_of(m.pos, m.level, levels));
    });
    partial[static_cast<std::size_t>(team.index())] = b;
  });
  SuperBlockBounds all;
  for (const SuperBlockBounds& b : partial) all.merge(b);
  return all;
}

CoarseOccupancy build_coarse_occupancy(const VoxelBlockMap& map, std::vector<int32_t>* cells) {
  const MapView view = map.view();
  const int levels = map.levels();
  const int32_t high_water = map.block_high_water();
  CoarseOccupancy grid = CoarseOccupancy::covering(
      super_block_bounds(view.meta, high_water, levels), view.level[levels - 1].block_size_m);
  const int64_t count = grid.cell_count();
  if (count == 0 || count > CoarseOccupancy::kMaxCells) return grid;
  cells->assign(static_cast<std::size_t>(count), 0);
  grid.cells = cells->data();
  parallel_for(high_water, [&](int64_t ptr) {
    const BlockMeta& m = view.meta[ptr];
    if (m.level >= 0) grid.mark(CoarseOccupancy::super_block_of(m.pos, m.level, levels));
  });
  return grid;
}

}  // namespace hivox::kernels

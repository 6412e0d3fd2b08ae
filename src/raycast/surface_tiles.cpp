#include "raycast/surface_tiles.h"

#include <algorithm>
#include <vector>

#include "core/parallel.h"
#include "hivox/map/voxel_block_map.h"

namespace hivox::kernels {

int64_t fill_range_tiles(const VoxelBlockMap& map, const PinholeCamera& camera, const Rigid3f& T_cw,
                         float min_depth_m, float max_depth_m, const RangeTiles& tiles) {
  const MapView view = map.view();
  const int32_t high_water = map.block_high_water();
  std::vector<int64_t> projected(static_cast<std::size_t>(thread_count()), 0);
  parallel_team([&](const ThreadTeam& team) {
    int64_t mine = 0;
    team.for_each(
        high_water,
        [&](int64_t ptr) {
          const BlockMeta& m = view.meta[ptr];
          if (m.level < 0) return;
          mine += project_block_to_tiles(T_cw, camera, m.pos, view.level[m.level].block_size_m,
                                         min_depth_m, max_depth_m, tiles);
        },
        CpuSchedule::dynamic(256));
    projected[static_cast<std::size_t>(team.index())] = mine;
  });
  int64_t total = 0;
  for (const int64_t n : projected) total += n;
  return total;
}

SurfaceTiles build_surface_tiles(const VoxelBlockMap& map, const PinholeCamera& camera,
                                 const Rigid3f& T_cw, const Vec3f& camera_centre_w,
                                 const RangeTiles& tiles, float min_depth_m, float max_depth_m,
                                 SurfaceTileStorage* storage) {
  const MapView view = map.view();
  const float pad_m = view.level[view.levels - 1].voxel_size_m;
  const int32_t high_water = map.block_high_water();
  const int tile_count = tiles.count();
  SurfaceTileStorage& s = *storage;
  s.rects.resize(4 * static_cast<std::size_t>(high_water));
  s.begin.resize(static_cast<std::size_t>(tile_count) + 1);
  // A block's grown box: its lowest corner and its side.
  auto box_of = [&](const BlockMeta& m, float* side_m) {
    const float block_m = view.level[m.level].block_size_m;
    *side_m = block_m + 2.0f * pad_m;
    return to_float(m.pos) * block_m - Vec3f{pad_m, pad_m, pad_m};
  };
  // Each thread takes every thread_count-th chunk of blocks, counts its boxes per tile, and
  // after the counts are summed writes them into slots of its own: no atomics, and a tile's boxes
  // always come in the same order.
  constexpr int32_t kChunk = 512;
  const int32_t chunks = (high_water + kChunk - 1) / kChunk;
  float* boxes = nullptr;
  std::size_t box_count = 0;
  parallel_team([&](const ThreadTeam& team) {
    const int thread = team.index(), threads = team.size();
    auto for_my_blocks = [&](auto&& body) {
      for (int32_t chunk = thread; chunk < chunks; chunk += threads)
        for (int32_t ptr = chunk * kChunk; ptr < std::min(high_water, (chunk + 1) * kChunk); ++ptr)
          body(ptr, &s.rects[4 * static_cast<std::size_t>(ptr)]);
    };
    team.single([&] { s.cursor.assign(static_cast<std::size_t>(threads) * tile_count, 0); });
    int32_t* cursor = &s.cursor[static_cast<std::size_t>(thread) * tile_count];
    for_my_blocks([&](int32_t ptr, int32_t* rect) {
      const BlockMeta& m = view.meta[ptr];
      rect[0] = rect[1] = 0;
      rect[2] = rect[3] = -1;  // no tiles
      if (m.level < 0 || m.surface.surface == 0) return;
      float side_m = 0.0f;
      const Vec3f origin = box_of(m, &side_m);
      TileRect r;
      if (!box_tile_rect(T_cw, camera, origin, side_m, min_depth_m, max_depth_m, tiles, &r)) return;
      rect[0] = r.tx0;
      rect[1] = r.ty0;
      rect[2] = r.tx1;
      rect[3] = r.ty1;
      for (int ty = r.ty0; ty <= r.ty1; ++ty)
        for (int tx = r.tx0; tx <= r.tx1; ++tx) ++cursor[ty * tiles.tiles_x + tx];
    });
    team.barrier();
    team.single([&] {
      // Per tile, the threads' slots one after the other; the cursors become the first slots.
      int32_t total = 0;
      for (int t = 0; t < tile_count; ++t) {
        s.begin[t] = total;
        for (int th = 0; th < threads; ++th) {
          int32_t& c = s.cursor[static_cast<std::size_t>(th) * tile_count + t];
          const int32_t n = c;
          c = total;
          total += n;
        }
      }
      s.begin[tile_count] = total;
      box_count = static_cast<std::size_t>(total);
      s.boxes.resize(6 * box_count);
      boxes = s.boxes.data();
    });
    // The boxes, relative to the camera centre, into this thread's slots of their tiles.
    for_my_blocks([&](int32_t ptr, const int32_t* rect) {
      if (rect[1] > rect[3]) return;
      float side_m = 0.0f;
      const Vec3f lo = box_of(view.meta[ptr], &side_m) - camera_centre_w;
      for (int ty = rect[1]; ty <= rect[3]; ++ty)
        for (int tx = rect[0]; tx <= rect[2]; ++tx) {
          const auto slot = static_cast<std::size_t>(cursor[ty * tiles.tiles_x + tx]++);
          for (int a = 0; a < 3; ++a) {
            boxes[a * box_count + slot] = lo[a];
            boxes[(3 + a) * box_count + slot] = lo[a] + side_m;
          }
        }
    });
  });
  SurfaceTiles out;
  out.begin = s.begin.data();
  for (int a = 0; a < 3; ++a) {
    out.lo[a] = boxes + a * box_count;
    out.hi[a] = boxes + (3 + a) * box_count;
  }
  return out;
}

}  // namespace hivox::kernels

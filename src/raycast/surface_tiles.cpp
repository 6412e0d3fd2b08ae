#include "raycast/surface_tiles.h"

#include <algorithm>

#include "hivox/core/parallel.h"
#include "hivox/map/voxel_block_map.h"

namespace hivox::kernels {

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
  SurfaceTiles out;
  out.begin = s.begin.data();
  // Each thread takes every thread_count-th chunk of blocks, counts its boxes per tile, and
  // after the counts are summed writes them into slots of its own: no atomics, and a tile's boxes
  // always come in the same order.
  constexpr int32_t kChunk = 512;
  const int32_t chunks = (high_water + kChunk - 1) / kChunk;
  parallel_threads([&](int thread, int threads) {
#pragma omp single
    s.cursor.assign(static_cast<std::size_t>(threads) * tile_count, 0);  // (then a barrier)
    int32_t* cursor = &s.cursor[static_cast<std::size_t>(thread) * tile_count];
    for (int32_t chunk = thread; chunk < chunks; chunk += threads)
      for (int32_t ptr = chunk * kChunk; ptr < std::min(high_water, (chunk + 1) * kChunk); ++ptr) {
        const BlockMeta& m = view.meta[ptr];
        int32_t* rect = &s.rects[4 * static_cast<std::size_t>(ptr)];
        TileRect r;
        if (m.level < 0 || m.surface.surface == 0 ||
            !box_tile_rect(
                T_cw, camera,
                to_float(m.pos) * view.level[m.level].block_size_m - Vec3f{pad_m, pad_m, pad_m},
                view.level[m.level].block_size_m + 2.0f * pad_m, min_depth_m, max_depth_m, tiles,
                &r)) {
          rect[0] = rect[1] = 0;
          rect[2] = rect[3] = -1;  // no tiles
          continue;
        }
        rect[0] = r.tx0;
        rect[1] = r.ty0;
        rect[2] = r.tx1;
        rect[3] = r.ty1;
        for (int ty = r.ty0; ty <= r.ty1; ++ty)
          for (int tx = r.tx0; tx <= r.tx1; ++tx) ++cursor[ty * tiles.tiles_x + tx];
      }
#pragma omp barrier
#pragma omp single
    {
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
      const std::size_t n = static_cast<std::size_t>(total);
      s.boxes.resize(6 * n);
      for (int a = 0; a < 3; ++a) {
        out.lo[a] = s.boxes.data() + a * n;
        out.hi[a] = s.boxes.data() + (3 + a) * n;
      }
    }  // (a barrier)
    // The boxes, relative to the camera centre, into this thread's slots of their tiles.
    float* lo_out[3] = {const_cast<float*>(out.lo[0]), const_cast<float*>(out.lo[1]),
                        const_cast<float*>(out.lo[2])};
    float* hi_out[3] = {const_cast<float*>(out.hi[0]), const_cast<float*>(out.hi[1]),
                        const_cast<float*>(out.hi[2])};
    for (int32_t chunk = thread; chunk < chunks; chunk += threads)
      for (int32_t ptr = chunk * kChunk; ptr < std::min(high_water, (chunk + 1) * kChunk); ++ptr) {
        const int32_t* rect = &s.rects[4 * static_cast<std::size_t>(ptr)];
        if (rect[1] > rect[3]) continue;
        const BlockMeta& m = view.meta[ptr];
        const float side_m = view.level[m.level].block_size_m + 2.0f * pad_m;
        const Vec3f lo = to_float(m.pos) * view.level[m.level].block_size_m -
                         Vec3f{pad_m, pad_m, pad_m} - camera_centre_w;
        for (int ty = rect[1]; ty <= rect[3]; ++ty)
          for (int tx = rect[0]; tx <= rect[2]; ++tx) {
            const auto slot = static_cast<std::size_t>(cursor[ty * tiles.tiles_x + tx]++);
            for (int a = 0; a < 3; ++a) {
              lo_out[a][slot] = lo[a];
              hi_out[a][slot] = lo[a] + side_m;
            }
          }
      }
  });
  return out;
}

}  // namespace hivox::kernels

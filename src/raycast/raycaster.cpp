#include "hivox/raycast/raycaster.h"

#include <algorithm>
#include <cfloat>

#include "hivox/core/parallel.h"
#include "hivox/core/timer.h"
#include "raycast/raycast_kernels.h"

namespace hivox {

Vec3f RaycastResult::point_c(int x, int y) const {
  return to_rigid3f(T_wc.inverse()) * points_w(x, y);
}

Vec3f RaycastResult::normal_c(int x, int y) const {
  return to_rigid3f(T_wc.inverse()).rotate(normals_w(x, y));
}

Raycaster::Raycaster(const RaycastParams& params) : params_(params) {
  params_.validate();
}

const RaycastResult& Raycaster::raycast(const VoxelBlockMap& map, const PinholeCamera& camera,
                                        const Pose& T_wc, RaycastStats* stats) {
  camera.validate("raycast camera");
  Stopwatch watch;
  RaycastResult& r = result_;
  const int w = camera.width, h = camera.height;
  if (r.depth_m.width() != w || r.depth_m.height() != h) {
    r.depth_m.resize(w, h);
    r.points_w.resize(w, h);
    r.normals_w.resize(w, h);
    r.colors.resize(w, h);
    r.levels.resize(w, h);
  }
  r.camera = camera;
  r.T_wc = T_wc;
  const MapView view = map.view();
  r.has_color = view.color != nullptr;

  // Range image: every allocated block's bounding box, projected.
  kernels::RangeTiles tiles;
  tiles.tile_px = params_.range_tile_px;
  tiles.tiles_x = (w + tiles.tile_px - 1) / tiles.tile_px;
  tiles.tiles_y = (h + tiles.tile_px - 1) / tiles.tile_px;
  const std::size_t tile_count = static_cast<std::size_t>(tiles.tiles_x) * tiles.tiles_y;
  tile_min_.assign(tile_count, FLT_MAX);
  tile_max_.assign(tile_count, 0.0f);
  tiles.z_min = tile_min_.data();
  tiles.z_max = tile_max_.data();
  const Rigid3f T_cw = to_rigid3f(T_wc.inverse());
  const int32_t high_water = map.block_high_water();
  int64_t projected = 0;
#pragma omp parallel for schedule(dynamic, 256) reduction(+ : projected)
  for (int32_t ptr = 0; ptr < high_water; ++ptr) {
    const BlockMeta& m = view.meta[ptr];
    if (m.level < 0) continue;
    projected +=
        kernels::project_block_to_tiles(T_cw, camera, m.pos, view.level[m.level].block_size_m,
                                        params_.min_depth_m, params_.max_depth_m, tiles);
  }
  const double range_ms = watch.lap_ms();

  // March one ray per pixel.
  const Rigid3f T = to_rigid3f(T_wc);
  kernels::RayMarchConstants k;
  k.mu_m = params_.truncation_m;
  k.step_fraction = params_.step_fraction;
  k.min_weight = params_.min_weight;
  k.min_step_voxels = std::min(
      2.0f, 0.5f * params_.truncation_m / map.params().voxel_size_at(map.levels() - 1) + 0.5f);
  int64_t hits = 0;
#pragma omp parallel reduction(+ : hits)
  {
    kernels::RayBlockCache cache;  // per thread, across the rays of its rows
#pragma omp for schedule(dynamic, 4)
    for (int y = 0; y < h; ++y) {
      const int ty = y / tiles.tile_px;
      for (int x = 0; x < w; ++x) {
        const int t = ty * tiles.tiles_x + x / tiles.tile_px;
        kernels::RayHit hit;
        const bool found =
            tile_max_[t] > 0.0f &&
            kernels::march_ray(view, cache, T.t,
                               T.rotate(camera.ray(static_cast<float>(x), static_cast<float>(y))),
                               tile_min_[t], tile_max_[t], k, &hit);
        if (!found) {
          r.depth_m(x, y) = 0.0f;
          r.points_w(x, y) = {};
          r.normals_w(x, y) = {};
          r.colors(x, y) = {};
          r.levels(x, y) = -1;
          continue;
        }
        ++hits;
        r.depth_m(x, y) = hit.depth_m;
        r.points_w(x, y) = hit.p_w;
        r.normals_w(x, y) = hit.normal_w;
        r.levels(x, y) = static_cast<int8_t>(hit.level);
        if (view.color != nullptr && hit.color_ptr >= 0) {
          const ColorVoxel c =
              view.color[static_cast<int64_t>(hit.color_ptr) * kBlockVoxels + hit.color_index];
          r.colors(x, y) = {c.r, c.g, c.b};
        } else {
          r.colors(x, y) = {};
        }
      }
    }
  }
  if (stats != nullptr) {
    stats->blocks_projected = projected;
    stats->hits = hits;
    stats->range_ms = range_ms;
    stats->march_ms = watch.lap_ms();
  }
  return r;
}

}  // namespace hivox

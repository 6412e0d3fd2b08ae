#include "hivox/raycast/raycaster.h"

#include <algorithm>
#include <cfloat>

#include "hivox/core/error.h"
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
                                        const Pose& T_wc, RaycastStats* stats,
                                        const DepthImage* start_hint_m) {
  camera.validate("raycast camera");
  if (start_hint_m != nullptr &&
      (start_hint_m->width() != camera.width || start_hint_m->height() != camera.height))
    fail(ErrorCode::InvalidArgument, "raycast start hint is {}x{} but the camera is {}x{}",
         start_hint_m->width(), start_hint_m->height(), camera.width, camera.height);
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
  const float hint_margin = params_.hint_margin_mu * params_.truncation_m;
  k.min_step_voxels = std::min(
      2.0f, 0.5f * params_.truncation_m / map.params().voxel_size_at(map.levels() - 1) + 0.5f);
  int64_t hits = 0;
#pragma omp parallel reduction(+ : hits)
  {
    kernels::BlockLookupCache cache;  // per thread, across the rays of its tiles
    // Tile by tile: neighbouring rays cross the same blocks, so their voxels stay in cache.
#pragma omp for schedule(dynamic, 8)
    for (int t = 0; t < static_cast<int>(tile_count); ++t) {
      const int x0 = (t % tiles.tiles_x) * tiles.tile_px, y0 = (t / tiles.tiles_x) * tiles.tile_px;
      const int x1 = std::min(w, x0 + tiles.tile_px), y1 = std::min(h, y0 + tiles.tile_px);
      for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) {
          const Vec3f dir = T.rotate(camera.ray(static_cast<float>(x), static_cast<float>(y)));
          // The hinted depth when a start `hint_margin` in front of it lies inside the ray's
          // range, else 0.
          float hint = start_hint_m != nullptr ? (*start_hint_m)(x, y) : 0.0f;
          if (!(hint > 0.0f && hint - hint_margin > tile_min_[t] &&
                hint - hint_margin < tile_max_[t]))
            hint = 0.0f;
          kernels::RayHit hit;
          bool found = false;
          if (hint > 0.0f && kernels::hit_near_hint(view, cache, T.t, dir, hint, k, &hit) &&
              hit.depth_m <= tile_max_[t]) {
            found = true;  // the usual case: the surface lies at the depth just fused
          } else if (tile_max_[t] > 0.0f) {
            bool behind = false;
            found = kernels::march_ray(view, cache, T.t, dir,
                                       hint > 0.0f ? hint - hint_margin : tile_min_[t],
                                       tile_max_[t], k, &hit, &behind);
            // The hint is wrong here (a model surface in front of it, e.g. at a depth edge, or
            // none behind it): search the part in front of the hint as well.
            if (hint > 0.0f && (!found || behind)) {
              kernels::RayHit front;
              if (kernels::march_ray(view, cache, T.t, dir, tile_min_[t], hint, k, &front)) {
                hit = front;
                found = true;
              }
            }
          }
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

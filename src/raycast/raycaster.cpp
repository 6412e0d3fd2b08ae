#include "hivox/raycast/raycaster.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <memory>

#include "core/parallel.h"
#include "hivox/core/error.h"
#include "hivox/core/timer.h"
#include "raycast/coarse_occupancy.h"
#include "raycast/cpu/ray_packets.h"
#include "raycast/cpu/tile_driver.h"
#include "raycast/raycast_kernels.h"
#include "raycast/surface_tiles.h"

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

Raycaster::~Raycaster() = default;
Raycaster::Raycaster(Raycaster&&) noexcept = default;
Raycaster& Raycaster::operator=(Raycaster&&) noexcept = default;

const RaycastResult& Raycaster::raycast(const VoxelBlockMap& map, const PinholeCamera& camera,
                                        const Pose& T_wc, const DepthRange& range,
                                        const RaycastHints& hints, RaycastStats* stats) {
  camera.validate("raycast camera");
  range.validate("raycast depth range");
  for (const auto& [image, name] :
       {std::pair{hints.start_m, "start hint"}, std::pair{hints.fallback_m, "fallback hint"}})
    if (image != nullptr && (image->width() != camera.width || image->height() != camera.height))
      fail(ErrorCode::InvalidArgument, "raycast {} is {}x{} but the camera is {}x{}", name,
           image->width(), image->height(), camera.width, camera.height);
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
  r.has_color = map.params().store_color;
  RaycastStats local;
  dispatch(map.device(), "raycasting",
           [&] { raycast_cpu(map, range, hints, stats != nullptr ? *stats : local); });
  return r;
}

void Raycaster::raycast_cpu(const VoxelBlockMap& map, const DepthRange& range,
                            const RaycastHints& hints, RaycastStats& stats) {
  Stopwatch watch;
  RaycastResult& r = result_;
  const PinholeCamera& camera = r.camera;
  const MapView view = map.view();
  const float min_depth_m = kernels::nearest_ray_start(range.min_m);
  const float max_depth_m = range.max_m;

  // Range image: every allocated block's bounding box, projected.
  const RaycastTuning& tuning = params_.tuning;
  kernels::RangeTiles tiles = kernels::RangeTiles::covering(tuning.range_tile_px, camera);
  const int tile_count = tiles.count();
  tile_min_.assign(static_cast<std::size_t>(tile_count), FLT_MAX);
  tile_max_.assign(static_cast<std::size_t>(tile_count), 0.0f);
  tiles.z_min = tile_min_.data();
  tiles.z_max = tile_max_.data();
  const Rigid3f T_cw = to_rigid3f(r.T_wc.inverse());
  stats.blocks_projected =
      kernels::fill_range_tiles(map, camera, T_cw, min_depth_m, max_depth_m, tiles);
  // Which super-blocks hold blocks: marches cross the others in one step.
  kernels::CoarseOccupancy occupancy;
  if (tuning.coarse_skipping) occupancy = kernels::build_coarse_occupancy(map, &occupancy_);
  // Which blocks hold a surface, per tile: marching rays march only where they cross them.
  cpu::TileRaycast cast;
  cast.T_wc = to_rigid3f(r.T_wc);
  const bool hinted = !hints.empty();
  if (tuning.surface_tiles == SurfaceTileUse::Always ||
      (tuning.surface_tiles == SurfaceTileUse::WithoutHints && !hinted)) {
    if (!surface_tiles_) surface_tiles_ = std::make_unique<kernels::SurfaceTileStorage>();
    cast.surface = kernels::build_surface_tiles(map, camera, T_cw, cast.T_wc.t, tiles, min_depth_m,
                                                max_depth_m, surface_tiles_.get());
  }
  stats.range_ms = watch.lap_ms();

  // One ray per pixel.
  cast.map = view;
  cast.camera = camera;
  cast.start_hint_m = hints.start_m;
  cast.fallback_hint_m = hints.fallback_m;
  cast.tiles = tiles;
  cast.k = kernels::march_constants(params_, view, occupancy);
  cast.packets = tuning.ray_packets && hinted && kernels::packets_can_address(view);
  cast.out = {r.depth_m.data(), r.points_w.data(), r.normals_w.data(), r.colors.data(),
              r.levels.data()};
  const cpu::RayCounts counts = cpu::cast_tiles(cast);
  stats.hits = counts.hits;
  stats.found_at_hint = counts.found_at_hint;
  stats.found_at_fallback = counts.found_at_fallback;
  stats.march_ms = watch.lap_ms();
}

}  // namespace hivox

#include "raycast/cpu/tile_driver.h"

#include <algorithm>
#include <memory>
#include <utility>
#include <vector>

#include "core/parallel.h"
#include "hivox/raycast/params.h"
#include "raycast/cpu/packet_search.h"

namespace hivox::cpu {
namespace {

/// One thread's state across the tiles it casts.
struct TileThread {
  kernels::BlockLookupCache cache;         ///< across the rays of its tiles
  std::unique_ptr<PacketScratch> scratch;  ///< with packets only
  RayCounts counts;
};

/// Casts the rays of tile `t`.
void cast_tile(const TileRaycast& c, int t, TileThread& th) {
  const MapView& view = c.map;
  const kernels::RangeTiles& tiles = c.tiles;
  const kernels::RayMarchConstants& k = c.k;
  const kernels::SurfaceTiles& surface = c.surface;
  const PinholeCamera& camera = c.camera;
  const Rigid3f& T = c.T_wc;
  const bool packets = c.packets;
  const int w = camera.width, h = camera.height;
  kernels::BlockLookupCache& cache = th.cache;
  PacketScratch* const scratch = th.scratch.get();
  auto write_pixel = [&](int x, int y, kernels::RayOutcome outcome, const kernels::RayHints& hints,
                         const kernels::RayHit& hit) {
    using kernels::RayOutcome;
    const bool found = outcome != RayOutcome::Miss;
    th.counts.hits += found;
    th.counts.found_at_hint += outcome == RayOutcome::AtHint || outcome == RayOutcome::AtSecondHint;
    th.counts.found_at_fallback += hints.found_at_fallback(outcome);
    kernels::write_ray(c.out, view, static_cast<int64_t>(y) * w + x, found, hit);
  };
  const int x0 = (t % tiles.tiles_x) * tiles.tile_px, y0 = (t / tiles.tiles_x) * tiles.tile_px;
  const int x1 = std::min(w, x0 + tiles.tile_px), y1 = std::min(h, y0 + tiles.tile_px);
  // The camera-frame rays' x and y components, per column and row of the tile (what
  // camera.ray gives, with a division per tile column and row rather than two per pixel).
  float ray_x[RaycastTuning::kMaxRangeTilePx], ray_y[RaycastTuning::kMaxRangeTilePx];
  for (int x = x0; x < x1; ++x) ray_x[x - x0] = camera.ray(static_cast<float>(x), 0.0f).x;
  for (int y = y0; y < y1; ++y) ray_y[y - y0] = camera.ray(0.0f, static_cast<float>(y)).y;
  // The ray of pixel (x, y) and its hints, written in place (a packet's ray copied in from a
  // temporary costs a stalled copy).
  auto set_ray = [&](int x, int y, PacketRay* ray) {
    auto depth_at = [&](const DepthImage* image) {
      return image != nullptr ? (*image)(x, y) : 0.0f;
    };
    ray->x = x;
    ray->y = y;
    ray->dir = T.rotate(Vec3f{ray_x[x - x0], ray_y[y - y0], 1.0f});
    ray->hints = kernels::ray_hints(depth_at(c.start_hint_m), depth_at(c.fallback_hint_m), k,
                                    c.tiles.z_min[t], c.tiles.z_max[t]);
    ray->at_second = false;
  };
  // The march of a ray whose hints failed or that has none (as cast_ray's), over the stretch
  // of it that crosses the tile's surface boxes (a miss when it crosses none).
  auto march = [&](const Vec3f& dir, float hint, kernels::RayHit* hit) {
    if (!(c.tiles.z_max[t] > 0.0f)) return kernels::RayOutcome::Miss;  // no block in range
    kernels::RayStretch stretch;
    if (!surface.empty() &&
        !surface.ray_stretch(t, kernels::inverse_direction(dir), c.tiles.z_min[t], c.tiles.z_max[t],
                             &stretch.z_in, &stretch.z_out))
      return kernels::RayOutcome::Miss;
    return kernels::march_from_hint(view, cache, T.t, dir, hint, c.tiles.z_min[t], c.tiles.z_max[t],
                                    k, hit, stretch)
               ? kernels::RayOutcome::Marched
               : kernels::RayOutcome::Miss;
  };
  int packed = 0;  // hinted rays waiting in the packet
  auto flush_packet = [&] {
    search_hints(view, cache, *scratch, T.t, packed, k, c.tiles.z_max[t]);
    // The rays whose search failed and that have a second hint search again, together: moved
    // to the front of the packet (their pixels go by their coordinates, and their failed
    // results need not be kept), searched at the second hint, and given their first hint
    // back for the march should that fail too.
    int retried = 0;
    for (int i = 0; i < packed; ++i) {
      PacketRay& ray = scratch->rays[i];
      if (scratch->found[i] || ray.hints.second == 0.0f) continue;
      std::swap(ray.hints.hint, ray.hints.second);
      ray.at_second = true;
      std::swap(scratch->rays[i], scratch->rays[retried]);
      std::swap(scratch->hits[i], scratch->hits[retried]);
      std::swap(scratch->found[i], scratch->found[retried]);
      ++retried;
    }
    if (retried > 0) search_hints(view, cache, *scratch, T.t, retried, k, c.tiles.z_max[t]);
    for (int j = 0; j < retried; ++j)
      std::swap(scratch->rays[j].hints.hint, scratch->rays[j].hints.second);
    for (int i = 0; i < packed; ++i) {
      using kernels::RayOutcome;
      const PacketRay& ray = scratch->rays[i];
      kernels::RayHit& hit = scratch->hits[i];
      // A packed ray has a hint inside the tile's range, so the range is not empty.
      RayOutcome outcome = ray.at_second ? RayOutcome::AtSecondHint : RayOutcome::AtHint;
      if (!scratch->found[i]) outcome = march(ray.dir, ray.hints.hint, &hit);
      write_pixel(ray.x, ray.y, outcome, ray.hints, hit);
    }
    packed = 0;
  };
  // The pixel's ray: in the packet's next slot (kept there if it is hinted), or without
  // packets here.
  PacketRay alone;
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) {
      PacketRay& ray = packets ? scratch->rays[packed] : alone;
      set_ray(x, y, &ray);
      if (packets && ray.hints.hint > 0.0f) {
        ray.inv_dir = kernels::inverse_direction(ray.dir);
        if (++packed == kPacketRays) flush_packet();
        continue;
      }
      kernels::RayHit hit;
      kernels::RayOutcome outcome =
          kernels::search_at_hints(view, cache, T.t, ray.dir, ray.hints, c.tiles.z_max[t], k, &hit);
      if (outcome == kernels::RayOutcome::Miss) outcome = march(ray.dir, ray.hints.hint, &hit);
      write_pixel(x, y, outcome, ray.hints, hit);
    }
  if (packed > 0) flush_packet();
}

}  // namespace

RayCounts cast_tiles(const TileRaycast& cast) {
  std::vector<RayCounts> counts(static_cast<std::size_t>(thread_count()));
  parallel_team([&](const ThreadTeam& team) {
    TileThread th;
    if (cast.packets) th.scratch = std::make_unique<PacketScratch>();
    // Tile by tile: neighbouring rays cross the same blocks, so their voxels stay in cache.
    team.for_each(
        cast.tiles.count(), [&](int64_t t) { cast_tile(cast, static_cast<int>(t), th); },
        CpuSchedule::dynamic(8));
    counts[static_cast<std::size_t>(team.index())] = th.counts;
  });
  RayCounts sum;
  for (const RayCounts& c : counts) {
    sum.hits += c.hits;
    sum.found_at_hint += c.found_at_hint;
    sum.found_at_fallback += c.found_at_fallback;
  }
  return sum;
}

}  // namespace hivox::cpu

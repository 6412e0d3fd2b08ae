#include "hivox/raycast/raycaster.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <memory>

#include "hivox/core/atomic.h"
#include "hivox/core/error.h"
#include "hivox/core/parallel.h"
#include "hivox/core/timer.h"
#include "raycast/ray_packets.h"
#include "raycast/raycast_kernels.h"
#include "raycast/surface_tiles.h"

namespace hivox {
namespace {

constexpr int kPacketRays = 64;

struct PacketRay {
  int x = 0, y = 0;
  Vec3f dir;
  Vec3f inv_dir;  ///< kernels::inverse_direction(dir)
  kernels::RayHints hints;
  bool at_second = false;  ///< searched again at `hints.second` after the search at `hints.hint`
};

/// One thread's packet: its rays, their search state and outcomes, and the cells it samples.
struct PacketScratch {
  PacketRay rays[kPacketRays];
  kernels::RayHit hits[kPacketRays];
  bool found[kPacketRays];
  kernels::HintSearch search[kPacketRays];
  kernels::CrossingBracket bracket[kPacketRays];
  // Per sample of a step (indexed by the step's list of live rays).
  int live[kPacketRays];
  float z[kPacketRays];
  Vec3f points[kPacketRays];
  Vec3f dirs[kPacketRays];
  Vec3f inv_dirs[kPacketRays];
  kernels::TsdfSample samples[kPacketRays];
  int levels[kPacketRays];
  bool sampled[kPacketRays];
  Vec3f ahead[kPacketRays];
  kernels::PacketLookups lookups;
  kernels::CellBatch<kPacketRays> cells;
  kernels::CellBatch<3 * kPacketRays> normal_cells;
};

/// `hit_near_hint` for the `n` rays of a packet, step by step: `found[i]` when ray i's surface
/// was found near its hint within `z_max` (`hits[i]` filled); the others march.
void search_hints(const MapView& map, kernels::BlockLookupCache& cache, PacketScratch& s,
                  const Vec3f& o, int n, const kernels::RayMarchConstants& k, float z_max) {
  using namespace kernels;
  const int min_w = k.min_weight;
  // The sample at the hint starts the search, and usually ends it: its cell holds the crossing.
  for (int i = 0; i < n; ++i) {
    s.found[i] = false;
    s.points[i] = o + s.rays[i].dir * s.rays[i].hints.hint;
    s.dirs[i] = s.rays[i].dir;
    s.inv_dirs[i] = s.rays[i].inv_dir;
  }
  sample_tsdf_packet(map, cache, s.lookups, n, s.points, s.dirs, s.inv_dirs, min_w, s.cells,
                     s.samples, s.levels, s.sampled);
  int live = 0;
  int bracketed[kPacketRays];
  int n_bracketed = 0;
  for (int i = 0; i < n; ++i) {
    if (!s.sampled[i]) continue;
    const PacketRay& ray = s.rays[i];
    if (s.samples[i].at_crossing()) {
      exact_bracket(map, ray.dir, ray.hints.hint, s.samples[i], s.levels[i], &s.bracket[i]);
      bracketed[n_bracketed++] = i;
    } else if (hint_search_begin(map, ray.dir, ray.hints.hint, s.samples[i], s.levels[i], k,
                                 &s.search[i])) {
      s.live[live++] = i;
    }
  }
  // Samples the live rays s.live[0, live) at the ray parameters `next(ray)` gives.
  auto sample_live = [&](int live_rays, auto&& next) {
    for (int j = 0; j < live_rays; ++j) {
      const int i = s.live[j];
      s.z[j] = next(i);
      s.points[j] = o + s.rays[i].dir * s.z[j];
      s.dirs[j] = s.rays[i].dir;
      s.inv_dirs[j] = s.rays[i].inv_dir;
    }
    sample_tsdf_packet(map, cache, s.lookups, live_rays, s.points, s.dirs, s.inv_dirs, min_w,
                       s.cells, s.samples, s.levels, s.sampled);
  };
  // Newton steps until the crossing is bracketed (or the ray gives up).
  while (live > 0) {
    sample_live(live, [&](int i) { return hint_search_next(s.search[i], k); });
    int kept = 0;
    for (int j = 0; j < live; ++j) {
      const int i = s.live[j];
      const HintStep step =
          hint_search_update(s.search[i], map, s.rays[i].dir, s.z[j], s.sampled[j], s.samples[j],
                             s.levels[j], &s.bracket[i]);
      if (step == HintStep::Bracketed) bracketed[n_bracketed++] = i;
      if (step == HintStep::Continue) s.live[kept++] = i;
    }
    live = kept;
  }
  // Secant steps until each bracket is short or exact.
  live = 0;
  for (int j = 0; j < n_bracketed; ++j)
    if (!s.bracket[bracketed[j]].exact) s.live[live++] = bracketed[j];
  while (live > 0) {
    sample_live(live, [&](int i) { return bracket_secant(s.bracket[i]); });
    int kept = 0;
    for (int j = 0; j < live; ++j) {
      const int i = s.live[j];
      if (!bracket_update(s.bracket[i], s.z[j], s.sampled[j], s.samples[j], s.levels[j]))
        s.live[kept++] = i;
    }
    live = kept;
  }
  // The hits within range, and their normals.
  int with_hit = 0;
  for (int j = 0; j < n_bracketed; ++j) {
    const int i = bracketed[j];
    bracket_hit(s.bracket[i], o, s.rays[i].dir, &s.hits[i]);
    if (s.hits[i].depth_m > z_max) continue;
    // The hit's colour is read when the packet is written out: fetch it while the normals are
    // computed (an uncached read per hit otherwise).
    if (map.color != nullptr && s.hits[i].color_ptr >= 0)
      __builtin_prefetch(&map.color[static_cast<int64_t>(s.hits[i].color_ptr) * kBlockVoxels +
                                    s.hits[i].color_index]);
    s.live[with_hit] = i;
    s.points[with_hit] = s.hits[i].p_w;
    s.levels[with_hit] = s.hits[i].level;
    ++with_hit;
  }
  samples_one_voxel_ahead_packet(map, cache, s.lookups, with_hit, s.points, s.levels, min_w,
                                 s.normal_cells, s.ahead, s.sampled);
  for (int j = 0; j < with_hit; ++j) {
    const int i = s.live[j];
    RayHit& hit = s.hits[i];
    hit.normal_w = s.sampled[j] ? normal_from_ahead(s.ahead[j], 0.0f)
                                : tsdf_normal_across_levels(map, cache, hit.p_w, 0.0f, hit.level,
                                                            min_w, s.bracket[i].best.gradient);
    s.found[i] = true;
  }
}

}  // namespace

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
  const DepthImage* start_hint_m = hints.start_m;
  const DepthImage* fallback_hint_m = hints.fallback_m;
  // Rays start no nearer than this: blocks at the camera's centre project without bound.
  constexpr float kNearestStart_m = 1e-3f;
  const float min_depth_m = std::max(range.min_m, kNearestStart_m);
  const float max_depth_m = range.max_m;
  for (const auto& [image, name] :
       {std::pair{start_hint_m, "start hint"}, std::pair{fallback_hint_m, "fallback hint"}})
    if (image != nullptr && (image->width() != camera.width || image->height() != camera.height))
      fail(ErrorCode::InvalidArgument, "raycast {} is {}x{} but the camera is {}x{}", name,
           image->width(), image->height(), camera.width, camera.height);
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
  const RaycastTuning& tuning = params_.tuning;
  kernels::RangeTiles tiles = kernels::RangeTiles::covering(tuning.range_tile_px, camera);
  const int tile_count = tiles.count();
  tile_min_.assign(static_cast<std::size_t>(tile_count), FLT_MAX);
  tile_max_.assign(static_cast<std::size_t>(tile_count), 0.0f);
  tiles.z_min = tile_min_.data();
  tiles.z_max = tile_max_.data();
  const Rigid3f T_cw = to_rigid3f(T_wc.inverse());
  const int64_t projected =
      kernels::fill_range_tiles(map, camera, T_cw, min_depth_m, max_depth_m, tiles);
  // Which super-blocks hold blocks: marches cross the others in one step.
  kernels::CoarseOccupancy occupancy;
  if (tuning.coarse_skipping) occupancy = kernels::build_coarse_occupancy(map, &occupancy_);
  // Which blocks hold a surface, per tile: marching rays march only where they cross them.
  const Rigid3f T = to_rigid3f(T_wc);
  kernels::SurfaceTiles surface;
  const bool hinted = !hints.empty();
  if (tuning.surface_tiles == SurfaceTileUse::Always ||
      (tuning.surface_tiles == SurfaceTileUse::WithoutHints && !hinted)) {
    if (!surface_tiles_) surface_tiles_ = std::make_unique<kernels::SurfaceTileStorage>();
    surface = kernels::build_surface_tiles(map, camera, T_cw, T.t, tiles, min_depth_m, max_depth_m,
                                           surface_tiles_.get());
  }
  const double range_ms = watch.lap_ms();

  // March one ray per pixel.
  const kernels::RayMarchConstants k = kernels::march_constants(params_, view, occupancy);
  const bool packets = tuning.ray_packets && hinted && kernels::packets_can_address(view);
  int64_t hits = 0, found_at_hint = 0, found_at_fallback = 0;
#pragma omp parallel reduction(+ : hits, found_at_hint, found_at_fallback)
  {
    kernels::BlockLookupCache cache;  // per thread, across the rays of its tiles
    std::unique_ptr<PacketScratch> scratch;
    if (packets) scratch = std::make_unique<PacketScratch>();
    const kernels::RaycastOutputView out{r.depth_m.data(), r.points_w.data(), r.normals_w.data(),
                                         r.colors.data(), r.levels.data()};
    auto write_pixel = [&](int x, int y, kernels::RayOutcome outcome,
                           const kernels::RayHints& hints, const kernels::RayHit& hit) {
      using kernels::RayOutcome;
      const bool found = outcome != RayOutcome::Miss;
      hits += found;
      found_at_hint += outcome == RayOutcome::AtHint || outcome == RayOutcome::AtSecondHint;
      found_at_fallback += hints.found_at_fallback(outcome);
      kernels::write_ray(out, view, static_cast<int64_t>(y) * w + x, found, hit);
    };
    // Tile by tile: neighbouring rays cross the same blocks, so their voxels stay in cache.
#pragma omp for schedule(dynamic, 8)
    for (int t = 0; t < tile_count; ++t) {
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
        ray->hints = kernels::ray_hints(depth_at(start_hint_m), depth_at(fallback_hint_m), k,
                                        tile_min_[t], tile_max_[t]);
        ray->at_second = false;
      };
      // The march of a ray whose hints failed or that has none (as cast_ray's), over the stretch
      // of it that crosses the tile's surface boxes (a miss when it crosses none).
      auto march = [&](const Vec3f& dir, float hint, kernels::RayHit* hit) {
        if (!(tile_max_[t] > 0.0f)) return kernels::RayOutcome::Miss;  // no block in range
        kernels::RayStretch stretch;
        if (!surface.empty() &&
            !surface.ray_stretch(t, kernels::inverse_direction(dir), tile_min_[t], tile_max_[t],
                                 &stretch.z_in, &stretch.z_out))
          return kernels::RayOutcome::Miss;
        return kernels::march_from_hint(view, cache, T.t, dir, hint, tile_min_[t], tile_max_[t], k,
                                        hit, stretch)
                   ? kernels::RayOutcome::Marched
                   : kernels::RayOutcome::Miss;
      };
      int packed = 0;  // hinted rays waiting in the packet
      auto flush_packet = [&] {
        search_hints(view, cache, *scratch, T.t, packed, k, tile_max_[t]);
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
        if (retried > 0) search_hints(view, cache, *scratch, T.t, retried, k, tile_max_[t]);
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
              kernels::search_at_hints(view, cache, T.t, ray.dir, ray.hints, tile_max_[t], k, &hit);
          if (outcome == kernels::RayOutcome::Miss) outcome = march(ray.dir, ray.hints.hint, &hit);
          write_pixel(x, y, outcome, ray.hints, hit);
        }
      if (packed > 0) flush_packet();
    }
  }
  if (stats != nullptr) {
    stats->blocks_projected = projected;
    stats->hits = hits;
    stats->found_at_hint = found_at_hint;
    stats->found_at_fallback = found_at_fallback;
    stats->range_ms = range_ms;
    stats->march_ms = watch.lap_ms();
  }
  return r;
}

}  // namespace hivox

// What the device's raycast costs, modelled on the CPU: every model ray of a frame cast alone
// with the shared kernels::cast_ray, as a GPU thread casts it (the same hints, range tiles and
// constants as the CUDA loop), timed one by one, and the times gathered into the GPU's warps
// (8x4 pixels). A warp takes as long as its slowest ray, and a raycast's warps run in one or two
// waves, so the kernel's time follows its slowest warps: the tail, not the mean, is what a change
// to the march must shorten. Each variant is timed in turns with the others
// (the same rays, `--rounds` times, the minimum per ray kept).
//
//   ray_cost ../shared/data/tum_fr1_rpy --frames 120 --at 119
//   ray_cost synthetic:desk?frames=60 --levels 1 --top 10
//
// Variants: `grid` (the coarse occupancy grid: empty super-blocks crossed in one step),
// `no-grid` (unallocated space crossed block by block) and `split` (with the grid, the marches
// of the rays whose hints failed split across their warp's lanes, kernels::march_lane: a warp
// searches its rays' hints together, then marches its failed rays one after another, each
// lane a stretch; its time is its slowest search plus, per marching ray, its slowest lane).

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <numeric>
#include <string>
#include <vector>

#include "hivox/core/error.h"
#include "hivox/io/dataset.h"
#include "hivox/pipeline/reconstruction.h"
#include "hivox/raycast/hints.h"
#include "hivox/raycast/raycaster.h"
#include "raycast/coarse_occupancy.h"
#include "raycast/raycast_kernels.h"
#include "raycast/surface_tiles.h"

namespace {

using namespace hivox;
using Clock = std::chrono::steady_clock;

constexpr int kWarpWidth = 8, kWarpHeight = 4;  // the CUDA raycast's warp of pixels

/// One ray: its inputs, how it ended and its best time.
struct Ray {
  Vec3f dir;
  float z_min = 0, z_max = 0;
  kernels::RayHints hints;
  kernels::RayOutcome outcome = kernels::RayOutcome::Miss;
  double ns = 1e30;     ///< split: the search at the hints only
  double march_ns = 0;  ///< split: the march's slowest lane per stretch, summed
  double lanes_ns = 0;  ///< split: all lanes' march times
  double whole_ns = 0;  ///< split: the ray cast whole (cast_ray), for warps that do not split
  float depth_m = 0;    ///< the hit's
};

const char* outcome_name(kernels::RayOutcome o) {
  switch (o) {
    case kernels::RayOutcome::AtHint:
      return "at hint";
    case kernels::RayOutcome::AtSecondHint:
      return "at second hint";
    case kernels::RayOutcome::Marched:
      return "marched";
    case kernels::RayOutcome::Miss:
      return "miss";
  }
  return "?";
}

/// A variant of the march: its constants (occupancy grid or none).
struct Variant {
  std::string name;
  kernels::RayMarchConstants k;
  bool split = false;
  std::vector<Ray> rays;
};

constexpr int kLanes = kWarpWidth * kWarpHeight;

/// Casts `r` as the split variant does, timing its parts; the hit's depth and the outcome.
void cast_split(const MapView& view, std::vector<kernels::BlockLookupCache>& lane_caches,
                const Vec3f& o, const kernels::RayMarchConstants& k, Ray& r, bool keep) {
  kernels::BlockLookupCache& cache = lane_caches.front();
  kernels::RayHit hit;
  Clock::time_point t0 = Clock::now();
  kernels::RayOutcome outcome =
      kernels::search_at_hints(view, cache, o, r.dir, r.hints, r.z_max, k, &hit);
  const double search_ns = std::chrono::duration<double, std::nano>(Clock::now() - t0).count();
  double march_ns = 0, lanes_ns = 0;
  if (outcome == kernels::RayOutcome::Miss && r.z_max > 0.0f) {
    // A warp's time on each stretch is its slowest lane's.
    double slowest = 0;
    auto each_lane = [&](int lane, auto&& march) {
      if (lane == 0) {
        march_ns += slowest;
        slowest = 0;
      }
      t0 = Clock::now();
      march();
      const double ns = std::chrono::duration<double, std::nano>(Clock::now() - t0).count();
      slowest = std::max(slowest, ns);
      lanes_ns += ns;
    };
    if (kernels::split_march_on_cpu(view, lane_caches.data(), o, r.dir, r.hints.hint, r.z_min,
                                    r.z_max, k, kLanes, &hit, each_lane))
      outcome = kernels::RayOutcome::Marched;
    march_ns += slowest;
  }
  kernels::RayHit unused;
  kernels::BlockLookupCache& whole_cache = lane_caches.back();
  t0 = Clock::now();
  kernels::cast_ray(view, whole_cache, o, r.dir, r.hints, r.z_min, r.z_max, k, &unused);
  const double whole_ns = std::chrono::duration<double, std::nano>(Clock::now() - t0).count();
  r.whole_ns = keep ? whole_ns : std::min(r.whole_ns, whole_ns);
  if (!keep && search_ns + march_ns >= r.ns + r.march_ns) return;
  r.ns = search_ns;
  r.march_ns = march_ns;
  r.lanes_ns = lanes_ns;
  r.outcome = outcome;
  r.depth_m = outcome == kernels::RayOutcome::Miss ? 0.0f : hit.depth_m;
}

void report(const Variant& v, const PinholeCamera& cam, int top, int split_at_most) {
  const int wx = (cam.width + kWarpWidth - 1) / kWarpWidth;
  const int wy = (cam.height + kWarpHeight - 1) / kWarpHeight;
  std::vector<double> warp_max(static_cast<std::size_t>(wx) * wy, 0.0);
  std::vector<int> warp_slowest(warp_max.size(), -1);
  std::vector<double> warp_marches(warp_max.size(), 0.0), warp_whole(warp_max.size(), 0.0);
  std::vector<int> warp_marching(warp_max.size(), 0);
  double total = 0;
  int64_t by_outcome[4] = {};
  double ns_by_outcome[4] = {};
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const int i = y * cam.width + x;
      const Ray& r = v.rays[static_cast<std::size_t>(i)];
      total += r.ns + r.lanes_ns;
      const auto o = static_cast<int>(r.outcome);
      ++by_outcome[o];
      ns_by_outcome[o] += r.ns + r.march_ns;
      const std::size_t w = static_cast<std::size_t>(y / kWarpHeight) * wx + x / kWarpWidth;
      if (r.ns > warp_max[w]) {
        warp_max[w] = r.ns;
        warp_slowest[w] = i;
      }
      warp_marches[w] += r.march_ns;
      warp_marching[w] += r.march_ns > 0.0;
      warp_whole[w] = std::max(warp_whole[w], r.whole_ns);
    }
  // A split warp searches together, then marches its failed rays one after another; with more
  // than `split_at_most` of them it casts them whole.
  for (std::size_t w = 0; w < warp_max.size(); ++w)
    warp_max[w] = warp_marching[w] > split_at_most ? warp_whole[w] : warp_max[w] + warp_marches[w];
  const double simt = std::accumulate(warp_max.begin(), warp_max.end(), 0.0);
  std::vector<std::size_t> order(warp_max.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return warp_max[a] > warp_max[b]; });
  auto pct = [&](double q) {
    return warp_max[order[static_cast<std::size_t>(q * (order.size() - 1))]];
  };
  // A warp's 32 lanes wait for its slowest ray: the share of their time spent on rays.
  const double lanes = kWarpWidth * kWarpHeight * simt;
  std::printf(
      "%s: rays %.2f ms in all (mean %.0f ns); warps %.2f ms (their slowest rays; lanes busy "
      "%.0f %% of it); slowest warp %.1f us, 99th/90th/50th percentile %.1f/%.1f/%.2f us\n",
      v.name.c_str(), total / 1e6, total / v.rays.size(), simt / 1e6, 100.0 * total / lanes,
      warp_max[order[0]] / 1e3, pct(0.01) / 1e3, pct(0.1) / 1e3, pct(0.5) / 1e3);
  std::printf("  outcomes:");
  for (int o = 0; o < 4; ++o)
    std::printf(" %s %lld (%.0f ns each)", outcome_name(static_cast<kernels::RayOutcome>(o)),
                static_cast<long long>(by_outcome[o]),
                by_outcome[o] > 0 ? ns_by_outcome[o] / by_outcome[o] : 0.0);
  std::printf("\n");
  for (int t = 0; t < top && t < static_cast<int>(order.size()); ++t) {
    const int i = warp_slowest[order[static_cast<std::size_t>(t)]];
    const Ray& r = v.rays[static_cast<std::size_t>(i)];
    std::printf(
        "  slow warp %d: ray (%d, %d) %.1f us, %s; range %.3f-%.3f m, hints %.3f / %.3f m\n", t,
        i % cam.width, i / cam.width, r.ns / 1e3, outcome_name(r.outcome), r.z_min, r.z_max,
        r.hints.hint, r.hints.second);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"The CUDA raycast's per-warp cost, modelled on the CPU with the shared ray code"};
  std::string spec;
  int frames = 120, at = -1, levels = 3, rounds = 3, top = 5;
  std::string dump;
  int split_at_most = kLanes;
  app.add_option("dataset", spec, "dataset folder or synthetic:NAME")->required();
  app.add_option("--frames", frames, "frames fused (the last is measured unless --at)");
  app.add_option("--at", at, "the frame whose raycast is measured (default: the last)");
  app.add_option("--levels", levels, "resolution levels (1 = fixed 2 mm grid)");
  app.add_option("--rounds", rounds, "times each ray is cast per variant (the minimum is kept)");
  app.add_option("--top", top, "slowest warps to describe");
  app.add_option("--split-at-most", split_at_most,
                 "split: warps with more marching rays cast them whole");
  app.add_option("--dump", dump,
                 "write every ray's outcome and hit depth (first variant) here, one line a ray: "
                 "two builds' files are equal where a change keeps the raycast's result");
  CLI11_PARSE(app, argc, argv);

  try {
    const std::unique_ptr<DatasetReader> reader = open_dataset(spec);
    const CameraRig& rig = reader->info().rig;
    const int n = std::min<int>(frames, static_cast<int>(reader->size()));
    if (at < 0 || at >= n) at = n - 1;
    if (at < 1)
      fail(ErrorCode::InvalidArgument, "--at {}: the raycast needs a frame before it", at);
    ReconstructionParams p;
    p.map.levels = levels;
    p.device = Device::cpu();
    Reconstruction loop(p, rig);
    const PinholeCamera cam = rig.depth_camera.subsampled(p.track.model_subsample);
    Raycaster raycaster(p.raycast);
    FrameHints frame_hints;
    RaycastResult previous;
    RaycastHints hints;
    Pose T_wc;
    for (int i = 0; i <= at; ++i) {
      const RgbdFrame f = reader->read(static_cast<std::size_t>(i));
      if (!f.T_wc_gt) fail(ErrorCode::InvalidArgument, "{}: frame {} has no ground truth", spec, i);
      loop.integrate(f, *f.T_wc_gt);
      T_wc = *f.T_wc_gt;
      // The loop's raycast after fusing: the frame's depth and the previous raycast as hints.
      hints = frame_hints.build(f.depth_m, rig.depth_camera, p.track.model_subsample, T_wc,
                                i > 0 ? &previous : nullptr, p.map.truncation_m);
      if (i < at) previous = raycaster.raycast(loop.map(), cam, T_wc, p.fusion.depth_range, hints);
    }
    const VoxelBlockMap& map = loop.map();
    const MapView view = map.view();
    std::printf("%s, frame %d: %lld blocks, %d levels; model raycast %dx%d\n", spec.c_str(), at,
                static_cast<long long>(map.blocks_in_use()), map.levels(), cam.width, cam.height);

    // Range tiles as the device fills them.
    const float min_m = std::max(p.fusion.depth_range.min_m, 1e-3f);
    kernels::RangeTiles tiles = kernels::RangeTiles::covering(p.raycast.tuning.range_tile_px, cam);
    std::vector<float> z_lo(static_cast<std::size_t>(tiles.count()), 3.4e38f),
        z_hi(static_cast<std::size_t>(tiles.count()), 0.0f);
    tiles.z_min = z_lo.data();
    tiles.z_max = z_hi.data();
    const Rigid3f T = to_rigid3f(T_wc);
    kernels::fill_range_tiles(map, cam, to_rigid3f(T_wc.inverse()), min_m,
                              p.fusion.depth_range.max_m, tiles);
    std::vector<int32_t> cells;
    std::vector<Variant> variants;
    variants.push_back(
        {"grid",
         kernels::march_constants(p.raycast, view, kernels::build_coarse_occupancy(map, &cells)),
         false,
         {}});
    variants.push_back({"no-grid",
                        kernels::march_constants(p.raycast, view, kernels::CoarseOccupancy{}),
                        false,
                        {}});
    variants.push_back({"split", variants.front().k, true, {}});

    const std::size_t pixels = static_cast<std::size_t>(cam.width) * cam.height;
    for (Variant& v : variants) {
      v.rays.resize(pixels);
      for (int y = 0; y < cam.height; ++y)
        for (int x = 0; x < cam.width; ++x) {
          Ray& r = v.rays[static_cast<std::size_t>(y) * cam.width + x];
          const int t = tiles.tile_of(x, y);
          r.z_min = tiles.z_min[t];
          r.z_max = tiles.z_max[t];
          const float start = hints.start_m != nullptr ? (*hints.start_m)(x, y) : 0.0f;
          const float fallback = hints.fallback_m != nullptr ? (*hints.fallback_m)(x, y) : 0.0f;
          r.hints = kernels::ray_hints(start, fallback, v.k, r.z_min, r.z_max);
          r.dir = T.rotate(cam.ray(static_cast<float>(x), static_cast<float>(y)));
        }
    }
    std::vector<kernels::BlockLookupCache> lane_caches(kLanes);
    for (int round = 0; round < rounds; ++round)
      for (Variant& v : variants)
        for (Ray& r : v.rays) {
          if (v.split) {
            cast_split(view, lane_caches, T.t, v.k, r, round == 0);
            continue;
          }
          kernels::BlockLookupCache cache;
          kernels::RayHit hit;
          const Clock::time_point t0 = Clock::now();
          r.outcome =
              kernels::cast_ray(view, cache, T.t, r.dir, r.hints, r.z_min, r.z_max, v.k, &hit);
          const double ns = std::chrono::duration<double, std::nano>(Clock::now() - t0).count();
          r.ns = std::min(r.ns, ns);
          r.depth_m = hit.depth_m;
        }
    for (const Variant& v : variants) report(v, cam, top, split_at_most);
    // The split marches against the whole ones: the same outcome and hit at (nearly) every ray?
    const std::vector<Ray>& whole = variants.front().rays;
    const std::vector<Ray>& split = variants.back().rays;
    int64_t outcome_differs = 0, depth_differs = 0, marched = 0;
    for (std::size_t i = 0; i < pixels; ++i) {
      marched += whole[i].outcome == kernels::RayOutcome::Marched ||
                 (whole[i].outcome == kernels::RayOutcome::Miss && whole[i].z_max > 0.0f);
      if (whole[i].outcome != split[i].outcome)
        ++outcome_differs;
      else if (std::abs(whole[i].depth_m - split[i].depth_m) > 1e-3f)
        ++depth_differs;
    }
    std::printf(
        "split against whole marches: %lld of %lld marching rays end otherwise, %lld hit "
        "more than 1 mm apart\n",
        static_cast<long long>(outcome_differs), static_cast<long long>(marched),
        static_cast<long long>(depth_differs));
    if (!dump.empty()) {
      FILE* out = std::fopen(dump.c_str(), "w");
      if (out == nullptr) fail(ErrorCode::Io, "--dump {}: cannot be written", dump);
      for (const Ray& r : variants.front().rays)
        std::fprintf(out, "%d %.7f\n", static_cast<int>(r.outcome), r.depth_m);
      std::fclose(out);
    }
  } catch (const Error& e) {
    std::fprintf(stderr, "ray_cost: %s\n", e.what());
    return 1;
  }
  return 0;
}

// What the device's raycast costs, modelled on the CPU: every model ray of a frame cast alone
// with the shared kernels::cast_ray, as a GPU thread casts it (the same hints, range tiles and
// constants as the CUDA loop), timed one by one, and the times gathered into the GPU's warps
// (8x4 pixels). A warp takes as long as its slowest ray, and a raycast's warps run in one or two
// waves, so the kernel's time follows its slowest warps: the tail, not the mean, is what a change
// to the march must shorten. The model shows the warps' divergence, not the latency of a GPU
// thread's look-ups (the CPU's memory caches are warm, the block cache has 4096 slots): a change
// that hides latency, such as splitting a march across a warp's lanes, it cannot judge. Its results
// for one depended on how its caches were kept (from 30 % less to 60 % more warp time), so the
// split marches are measured on a GPU only. Each variant is timed in turns with the others
// (the same rays, `--rounds` times, the minimum per ray kept).
//
//   ray_cost ../shared/data/tum_fr1_rpy --frames 120 --at 119
//   ray_cost synthetic:desk?frames=60 --levels 1 --top 10
//
// Each variant also models the device's ways with the marches (the rays whose search at their
// hints fails): split across a warp's lanes where at most 1, 8 or 32 of its rays march
// (set_split_marches), and the raycast as two kernels (set_queued_marches), the searches' warps
// then timed by their searches alone and each march a warp's.
//
// `--split-accuracy 0 0.6` also marches every ray of the model camera without hints (as a
// render's rays march), from the frame's pose and moved back by each distance given, whole and
// split across a warp's 32 lanes, and compares both with a dense march (0.5 mm steps, nothing
// skipped): which of the two finds the ray's first crossing where they differ.
//
// Variants: `grid` (the coarse occupancy grid: empty super-blocks crossed in one step),
// `no-grid` (unallocated space crossed block by block) and `level-hints` (the grid, and each
// ray's first look-up starting at the level its pixel hit in the raycast before, as the device's
// rays start). Each variant also counts the rays' hash-table look-ups (a fresh block cache per
// ray, as a GPU thread's): on a GPU each is a chain of dependent reads, and a warp waits for its
// lane with the most; the counts are exact where the times are noisy. The device's allocation
// walk over the frame's band (find_blocks) is counted likewise, a pixel. With levels, the rays
// that sampled a cell across levels (a corner stored at another level) are counted apart: what
// they cost against the others, and the share of the warps' time in warps that hold one. The
// marching rays are split by where they ended against their hint (or had none), with their
// marches' time. `--subsample 4` models the raycast at a quarter of the frame's resolution.

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <memory>
#include <numeric>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "fusion/fusion_kernels.h"
#include "hivox/core/error.h"
#include "hivox/io/dataset.h"
#include "hivox/map/hierarchy_edit.h"
#include "hivox/pipeline/reconstruction.h"
#include "hivox/raycast/hints.h"
#include "hivox/raycast/raycaster.h"
#include "map/sample_kernels.h"
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
  double ns = 1e30;
  double hint_ns = 1e30;  ///< its search at the hints alone (kernels::search_at_hints)
  int64_t lookups = 0;    ///< of the hash tables (the ray's block cache starts empty)
  int64_t cross_level = 0, irregular = 0;  ///< cells sampled across levels, irregular ones
  float depth_m = 0;                       ///< the hit's
  int level = -1;                          ///< the hit's
  /// Its search at the hints failed (or it had none) and it had a range to march.
  bool marched() const {
    return (outcome == kernels::RayOutcome::Marched || outcome == kernels::RayOutcome::Miss) &&
           z_max > 0.0f;
  }
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
  bool level_hints = false;  ///< each ray's search starts at the level its pixel hit last time
  std::vector<Ray> rays;
};

/// a / b (0 when b is 0).
double ratio(int64_t a, int64_t b) {
  return b > 0 ? static_cast<double>(a) / static_cast<double>(b) : 0.0;
}

void report(const Variant& v, const PinholeCamera& cam, int top) {
  const int wx = (cam.width + kWarpWidth - 1) / kWarpWidth;
  const int wy = (cam.height + kWarpHeight - 1) / kWarpHeight;
  std::vector<double> warp_max(static_cast<std::size_t>(wx) * wy, 0.0);
  std::vector<int> warp_slowest(warp_max.size(), -1);
  std::vector<int64_t> warp_lookups(warp_max.size(), 0);
  double total = 0;
  int64_t by_outcome[4] = {}, lookups_by_outcome[4] = {}, lookups = 0;
  double ns_by_outcome[4] = {};
  int64_t hits_by_level[kMaxLevels] = {};
  // Rays that sampled a cell across levels (a corner at another level), [1] below, and the
  // others [0]: their count found at their hint and its time; the warps that hold one.
  int64_t cross = 0, irregular_rays = 0, cells = 0, irregular = 0, at_hint[2] = {},
          at_hint_lookups[2] = {};
  double at_hint_ns[2] = {};
  std::vector<uint8_t> warp_cross(warp_max.size(), 0);
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const int i = y * cam.width + x;
      const Ray& r = v.rays[static_cast<std::size_t>(i)];
      total += r.ns;
      const auto o = static_cast<int>(r.outcome);
      ++by_outcome[o];
      ns_by_outcome[o] += r.ns;
      lookups_by_outcome[o] += r.lookups;
      lookups += r.lookups;
      if (r.level >= 0 && r.level < kMaxLevels) ++hits_by_level[r.level];
      const std::size_t w = static_cast<std::size_t>(y / kWarpHeight) * wx + x / kWarpWidth;
      warp_lookups[w] = std::max(warp_lookups[w], r.lookups);
      if (r.ns > warp_max[w]) {
        warp_max[w] = r.ns;
        warp_slowest[w] = i;
      }
      const bool c = r.cross_level > 0;
      cross += c;
      irregular_rays += r.irregular > 0;
      cells += r.cross_level;
      irregular += r.irregular;
      if (r.outcome == kernels::RayOutcome::AtHint) {
        ++at_hint[c];
        at_hint_ns[c] += r.ns;
        at_hint_lookups[c] += r.lookups;
      }
      warp_cross[w] |= c;
    }
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
  // The device's ways with the rays that march (their search at their hints failed; a march's
  // time: the ray's less its search), per warp: its slowest search, its marches and their time.
  std::vector<double> hint_max(warp_max.size(), 0.0), march_sum(warp_max.size(), 0.0);
  std::vector<int> marching(warp_max.size(), 0);
  std::vector<double> marches;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const Ray& r = v.rays[static_cast<std::size_t>(y) * cam.width + x];
      const std::size_t w = static_cast<std::size_t>(y / kWarpHeight) * wx + x / kWarpWidth;
      hint_max[w] = std::max(hint_max[w], r.hint_ns);
      if (r.marched()) {
        marches.push_back(std::max(r.ns - r.hint_ns, 0.0));
        ++marching[w];
        march_sum[w] += marches.back();
      }
    }
  auto slowest_first = [](std::vector<double> d) {
    std::sort(d.begin(), d.end(), std::greater<>());
    return d;
  };
  auto at = [](const std::vector<double>& d, double q) {
    return d.empty() ? 0.0 : d[static_cast<std::size_t>(q * (d.size() - 1))];
  };
  // Split marches (cast_rays_kernel<true>): a warp where at most n rays march searches its rays'
  // hints, then takes its marches one after another, each across the 32 lanes. A lane marches a
  // 32nd of the stretch, so the march would take a 32nd of its time at best; /8 if the lanes'
  // look-ups were four times what a 32nd of the march's are.
  for (const int n : {1, 8, 32})
    for (const double speedup : {32.0, 8.0}) {
      std::vector<double> t(warp_max.size());
      int split_warps = 0;
      for (std::size_t w = 0; w < t.size(); ++w) {
        const bool split = marching[w] > 0 && marching[w] <= n;
        split_warps += split;
        t[w] = split ? hint_max[w] + march_sum[w] / speedup : warp_max[w];
      }
      t = slowest_first(std::move(t));
      std::printf(
          "  split marches of up to %d rays a warp, a march %.0fx faster split: %d warps split; "
          "warps %.2f ms, slowest %.1f us, 99th/90th percentile %.1f/%.1f us\n",
          n, speedup, split_warps, std::accumulate(t.begin(), t.end(), 0.0) / 1e6, at(t, 0) / 1e3,
          at(t, 0.01) / 1e3, at(t, 0.1) / 1e3);
    }
  // The raycast as two kernels (GpuReconstruction::set_queued_marches): each warp of the first
  // waits for its slowest search, the second, a march a warp, for its slowest march.
  const std::vector<double> searches = slowest_first(hint_max);
  marches = slowest_first(std::move(marches));
  std::printf(
      "  as two kernels: the searches at the hints' warps %.2f ms, slowest %.1f us, 99th/90th/"
      "50th percentile %.1f/%.1f/%.2f us; %zu marches, slowest %.1f us, 10th/50th %.1f/%.2f "
      "us (each across a warp's lanes, 32x to 8x faster: the slowest %.1f-%.1f us)\n",
      std::accumulate(searches.begin(), searches.end(), 0.0) / 1e6, at(searches, 0) / 1e3,
      at(searches, 0.01) / 1e3, at(searches, 0.1) / 1e3, at(searches, 0.5) / 1e3, marches.size(),
      at(marches, 0) / 1e3, at(marches, 0.1) / 1e3, at(marches, 0.5) / 1e3, at(marches, 0) / 32e3,
      at(marches, 0) / 8e3);
  std::printf("  outcomes:");
  for (int o = 0; o < 4; ++o)
    std::printf(" %s %lld (%.0f ns each)", outcome_name(static_cast<kernels::RayOutcome>(o)),
                static_cast<long long>(by_outcome[o]),
                by_outcome[o] > 0 ? ns_by_outcome[o] / by_outcome[o] : 0.0);
  std::printf("\n");
  {
    // The marching rays (their search at the hints failed, or they had none) by where they
    // ended against their hint: their count, their marches' time and the slowest march. A ray
    // without a hint has neither the frame's depth nor the warped previous raycast at its pixel
    // (on fr1/rpy: the depth image's invalid border, and the strip the camera turned towards).
    const char* names[] = {
        "no hint, hit", "no hint, miss", "hint, miss",  "hit within a band of it",
        "within 5 cm",  "within 20 cm",  "beyond 20 cm"};
    int64_t count[7] = {};
    double sum[7] = {}, most[7] = {};
    for (const Ray& r : v.rays) {
      if (!r.marched()) continue;
      const bool hit = r.outcome == kernels::RayOutcome::Marched;
      const float off = std::abs(r.depth_m - r.hints.hint);
      const int b = r.hints.hint <= 0.0f ? (hit ? 0 : 1)
                    : !hit               ? 2
                    : off <= v.k.mu_m    ? 3
                    : off <= 0.05f       ? 4
                    : off <= 0.2f        ? 5
                                         : 6;
      const double t = std::max(r.ns - r.hint_ns, 0.0);
      ++count[b];
      sum[b] += t;
      most[b] = std::max(most[b], t);
    }
    std::printf("  marches by their end:");
    for (int b = 0; b < 7; ++b)
      std::printf("%s %s %lld (%.2f ms, slowest %.1f us)", b > 0 ? ";" : "", names[b],
                  static_cast<long long>(count[b]), sum[b] / 1e6, most[b] / 1e3);
    std::printf("\n");
  }
  // Each look-up the cache does not answer is a chain of dependent reads on a GPU; a warp waits
  // for its lane with the most.
  std::printf("  table look-ups: %.2f a ray (",
              ratio(lookups, static_cast<int64_t>(v.rays.size())));
  for (int o = 0; o < 4; ++o)
    std::printf("%s%s %.2f", o > 0 ? ", " : "", outcome_name(static_cast<kernels::RayOutcome>(o)),
                ratio(lookups_by_outcome[o], by_outcome[o]));
  std::printf("); warps' most: %.2f a warp\n",
              ratio(std::accumulate(warp_lookups.begin(), warp_lookups.end(), int64_t{0}),
                    static_cast<int64_t>(warp_lookups.size())));
  // What the rays across levels cost against the others, and the share of the warps' time in
  // the warps that hold one.
  if (cross > 0) {
    double warp_ns[2] = {};
    int64_t warps[2] = {};
    for (std::size_t w = 0; w < warp_max.size(); ++w) {
      ++warps[warp_cross[w]];
      warp_ns[warp_cross[w]] += warp_max[w];
    }
    const auto mean = [](double sum, int64_t n) { return n > 0 ? sum / n : 0.0; };
    std::printf(
        "  across levels: %lld rays (%.1f %%) sampled %lld cells across levels (%lld rays, %lld "
        "cells irregular); found at their hint %.0f ns (%.2f look-ups) with such cells, %.0f ns "
        "(%.2f) without; warps "
        "holding such a ray %lld (%.1f %%), %.2f us each, the others %.2f us (%.0f %% of the "
        "warps' time)\n",
        static_cast<long long>(cross), 100.0 * ratio(cross, static_cast<int64_t>(v.rays.size())),
        static_cast<long long>(cells), static_cast<long long>(irregular_rays),
        static_cast<long long>(irregular), mean(at_hint_ns[1], at_hint[1]),
        ratio(at_hint_lookups[1], at_hint[1]), mean(at_hint_ns[0], at_hint[0]),
        ratio(at_hint_lookups[0], at_hint[0]), static_cast<long long>(warps[1]),
        100.0 * ratio(warps[1], warps[0] + warps[1]), mean(warp_ns[1], warps[1]) / 1e3,
        mean(warp_ns[0], warps[0]) / 1e3, 100.0 * warp_ns[1] / simt);
  }
  std::printf("  hits by level:");
  for (int l = 0; l < kMaxLevels; ++l)
    if (hits_by_level[l] > 0) std::printf(" %d: %lld", l, static_cast<long long>(hits_by_level[l]));
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

/// The device's allocation walk (find_blocks) as a thread walks it: its pixels' truncation bands
/// one after another, each from the coarsest level down through Split blocks, its visitor
/// remembering the blocks it looked up in `slots` slots (as the device's FindVisitor: 1, the
/// last block, for a thread of one pixel; 16 for several): a block's side effects (its stamp, its
/// missing key) are done at its first look-up, so a thread visits the same blocks with fewer
/// look-ups. Counts the hash-table look-ups, by level.
struct WalkCounter {
  const MapView& map;
  uint32_t count = 1;  ///< slots used, 1 or 16
  int64_t lookups[kMaxLevels] = {};
  kernels::BlockSlot slots[16];
  void reset() {
    for (kernels::BlockSlot& s : slots) s = {};
  }
  int32_t block(int level, const Vec3i& pos) {
    kernels::BlockSlot& s = slots[kernels::block_slot(level, pos, count)];
    if (s.holds(level, pos)) return s.ptr;
    ++lookups[level];
    s = {pos, level, find_block_ptr(map.level[level], pos)};
    return s.ptr;
  }
};

/// The map's level boundaries: faces between leaf blocks stored at different levels (counted
/// once, from the finer side, in m^2), and the split parents with no split block among their 26
/// neighbours at their level (an island of finer blocks, with a boundary all round).
void report_levels(const VoxelBlockMap& map) {
  const MapView view = map.view();
  const std::vector<BlockRef> leaves = map.allocated_blocks();
  std::vector<double> boundary_m2(static_cast<std::size_t>(view.levels), 0.0);
  std::vector<BlockKey> parents;
  for (const BlockRef& b : leaves) {
    if (b.level + 1 < view.levels) parents.push_back({parent_block_pos(b.pos), b.level + 1});
    const double face = static_cast<double>(view.level[b.level].block_size_m);
    for (int axis = 0; axis < 3; ++axis)
      for (int side : {-1, 1}) {
        Vec3i n = b.pos;
        n[axis] += side;
        if (find_block_ptr(view.level[b.level], n) != kPtrEmpty) continue;  // same level, finer
        for (int l = b.level + 1; l < view.levels; ++l) {
          n = parent_block_pos(n);
          const int32_t ptr = find_block_ptr(view.level[l], n);
          if (ptr >= 0) boundary_m2[static_cast<std::size_t>(b.level)] += face * face;
          if (ptr != kPtrSplit) break;  // a coarser leaf, or nothing stored there
        }
      }
  }
  std::sort(parents.begin(), parents.end());
  parents.erase(std::unique(parents.begin(), parents.end()), parents.end());
  // Every split entry (the map's count); of the parents of leaves, those with no split neighbour.
  const std::vector<int64_t> split = map.split_entries_per_level();
  std::vector<int64_t> isolated(static_cast<std::size_t>(view.levels), 0);
  for (const BlockKey& p : parents) {
    int neighbours = 0;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
          neighbours += (dx | dy | dz) != 0 &&
                        find_block_ptr(view.level[p.level], p.pos + Vec3i{dx, dy, dz}) == kPtrSplit;
    isolated[static_cast<std::size_t>(p.level)] += neighbours == 0;
  }
  const std::vector<int64_t> per_level = map.blocks_per_level();
  for (int l = 0; l < view.levels; ++l) {
    std::printf("level %d: %lld blocks", l, static_cast<long long>(per_level[l]));
    if (l + 1 < view.levels)
      std::printf(", %.3f m^2 of faces against a coarser level", boundary_m2[l]);
    if (l > 0)
      std::printf(", %lld split (%lld with no split neighbour)", static_cast<long long>(split[l]),
                  static_cast<long long>(isolated[l]));
    std::printf("\n");
  }
}

/// The look-ups of frame `f`'s allocation walk over `map` at its true pose, a valid pixel, with
/// threads of 1, 2x1 and 2x2 pixels (GpuReconstruction::set_allocation_pixels).
void report_walk(const MapView& map, const RgbdFrame& f, const CameraRig& rig,
                 const ReconstructionParams& p) {
  kernels::DepthFrameView depth;
  depth.depth_m = {f.depth_m.data(), f.depth_m.width(), f.depth_m.height()};
  depth.camera = rig.depth_camera;
  depth.min_depth_m = std::max(p.fusion.depth_range.min_m, 1e-6f);
  depth.max_depth_m = p.fusion.depth_range.max_m;
  const Rigid3f T = to_rigid3f(*f.T_wc_gt);
  for (auto [w, h] : {std::pair{1, 1}, std::pair{2, 1}, std::pair{2, 2}}) {
    WalkCounter walk{map, w * h == 1 ? 1u : 16u};
    int64_t pixels = 0;
    for (int ty = 0; ty < depth.depth_m.height; ty += h)
      for (int tx = 0; tx < depth.depth_m.width; tx += w) {
        walk.reset();  // a thread's pixels
        for (int y = ty; y < std::min(ty + h, depth.depth_m.height); ++y)
          for (int x = tx; x < std::min(tx + w, depth.depth_m.width); ++x) {
            Vec3f a, b;
            if (!kernels::band_segment(depth, T, map.truncation_m, x, y, &a, &b)) continue;
            ++pixels;
            kernels::walk_segment(map, a, b, walk);
          }
      }
    int64_t all = 0;
    for (int l = 0; l < map.levels; ++l) all += walk.lookups[l];
    std::printf(
        "allocation walk, %dx%d pixels a thread: %lld pixels, %.2f table look-ups a pixel (", w, h,
        static_cast<long long>(pixels), ratio(all, pixels));
    for (int l = 0; l < map.levels; ++l)
      std::printf("%slevel %d: %.2f", l > 0 ? ", " : "", l, ratio(walk.lookups[l], pixels));
    std::printf(")\n");
  }
}

/// Range tiles as the device fills them: every block of `map` projected for `cam` at `T_wc`
/// within `range`, the tiles' depths in `z_min` and `z_max`.
kernels::RangeTiles filled_tiles(const VoxelBlockMap& map, const PinholeCamera& cam, int tile_px,
                                 const Pose& T_wc, const DepthRange& range,
                                 std::vector<float>* z_min, std::vector<float>* z_max) {
  kernels::RangeTiles tiles = kernels::RangeTiles::covering(tile_px, cam);
  z_min->assign(static_cast<std::size_t>(tiles.count()), 3.4e38f);
  z_max->assign(static_cast<std::size_t>(tiles.count()), 0.0f);
  tiles.z_min = z_min->data();
  tiles.z_max = z_max->data();
  kernels::fill_range_tiles(map, cam, to_rigid3f(T_wc.inverse()), std::max(range.min_m, 1e-3f),
                            range.max_m, tiles);
  return tiles;
}

/// The first crossing on a ray by a dense march (a sample every `step_m` of ray parameter,
/// nothing skipped): the first sample at or behind a surface whose sample before
/// was in front of it, or that follows unobserved space and is within the band behind a surface
/// (where march_ray searches back). 0: none.
float dense_first_crossing(const MapView& map, const Vec3f& o, const Vec3f& d, float z_min,
                           float z_max, int min_weight, float step_m) {
  kernels::BlockLookupCache cache;
  bool prev_valid = false;
  float prev_f = 0.0f;
  for (float z = z_min; z <= z_max; z += step_m) {
    kernels::TsdfSample s;
    int level;
    if (!kernels::sample_tsdf(map, cache, o + d * z, min_weight, &s, &level)) {
      prev_valid = false;
      continue;
    }
    if (s.f <= 0.0f && (prev_valid ? prev_f > 0.0f : s.f > -1.0f)) return z;
    prev_valid = true;
    prev_f = s.f;
  }
  return 0.0f;
}

/// How a march's hits compare with the dense march's first crossings.
struct CrossingTally {
  int64_t same = 0, missed = 0, later = 0, earlier = 0, extra = 0;
  void add(bool hit, float depth_m, float first_m, float within_m) {
    if (first_m == 0.0f) {
      ++(hit ? extra : same);
    } else if (!hit) {
      ++missed;
    } else if (std::abs(depth_m - first_m) <= within_m) {
      ++same;
    } else {
      ++(depth_m > first_m ? later : earlier);
    }
  }
  void print(const char* name) const {
    std::printf(
        "  %-6s marches: %lld as the dense march, %lld missed its crossing, %lld hit later, %lld "
        "earlier, %lld hit where it found none\n",
        name, static_cast<long long>(same), static_cast<long long>(missed),
        static_cast<long long>(later), static_cast<long long>(earlier),
        static_cast<long long>(extra));
  }
};

/// Every ray of `cam` at `T_wc` marched without a hint (as a render's are) over its range tile,
/// whole and split across 32 lanes (GpuReconstruction::set_split_marches and
/// set_queued_marches' marches), each compared with a dense march of 0.5 mm steps: which of the
/// two finds the first crossing where they differ.
void report_split_accuracy(const VoxelBlockMap& map, const kernels::RayMarchConstants& k,
                           const PinholeCamera& cam, int tile_px, const Pose& T_wc,
                           const DepthRange& range, const char* name) {
  const MapView view = map.view();
  std::vector<float> z_lo, z_hi;
  const kernels::RangeTiles tiles = filled_tiles(map, cam, tile_px, T_wc, range, &z_lo, &z_hi);
  const Rigid3f T = to_rigid3f(T_wc);
  std::vector<kernels::BlockLookupCache> lanes(32);
  kernels::BlockLookupCache cache;
  CrossingTally whole, split;
  int64_t rays = 0, one_only = 0, apart = 0;
  constexpr float kWithinM = 0.002f;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const int t = tiles.tile_of(x, y);
      const float z_min = tiles.z_min[t], z_max = tiles.z_max[t];
      if (!(z_min <= z_max)) continue;
      ++rays;
      const Vec3f dir = T.rotate(cam.ray(static_cast<float>(x), static_cast<float>(y)));
      kernels::RayHit a, b;
      const bool hit_a = kernels::march_from_hint(view, cache, T.t, dir, 0.0f, z_min, z_max, k, &a);
      const bool hit_b =
          kernels::split_march_on_cpu(view, lanes.data(), T.t, dir, 0.0f, z_min, z_max, k, 32, &b);
      one_only += hit_a != hit_b;
      apart += hit_a && hit_b && std::abs(a.depth_m - b.depth_m) > kWithinM;
      const float first = dense_first_crossing(view, T.t, dir, z_min, z_max, k.min_weight, 0.0005f);
      whole.add(hit_a, a.depth_m, first, kWithinM);
      split.add(hit_b, b.depth_m, first, kWithinM);
    }
  std::printf(
      "split marches without hints, %s (%dx%d): %lld rays, %lld hit by one march only, %lld hits "
      "more than 2 mm apart; against a dense march:\n",
      name, cam.width, cam.height, static_cast<long long>(rays), static_cast<long long>(one_only),
      static_cast<long long>(apart));
  whole.print("whole");
  split.print("split");
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"The CUDA raycast's per-warp cost, modelled on the CPU with the shared ray code"};
  std::string spec;
  int frames = 120, at = -1, levels = 3, rounds = 3, top = 5;
  int subsample = TrackParams{}.model_subsample;
  std::string dump;
  std::vector<double> split_accuracy;
  app.add_option("dataset", spec, "dataset folder or synthetic:NAME")->required();
  app.add_option("--frames", frames, "frames fused (the last is measured unless --at)");
  app.add_option("--at", at, "the frame whose raycast is measured (default: the last)");
  app.add_option("--levels", levels, "resolution levels (1 = fixed 2 mm grid)");
  app.add_option("--subsample", subsample,
                 "the model raycast at 1/N of the frame's resolution (1, 2 or 4)");
  app.add_option("--rounds", rounds, "times each ray is cast per variant (the minimum is kept)");
  app.add_option("--top", top, "slowest warps to describe");
  app.add_option("--dump", dump,
                 "write every ray's outcome and hit depth (last variant) here, one line a ray: "
                 "two builds' files are equal where a change keeps the raycast's result");
  app.add_option("--split-accuracy", split_accuracy,
                 "also march every ray of the model camera without hints, whole and split "
                 "across a warp, from the frame's pose moved back by each of these metres, and "
                 "compare both with a dense march")
      ->expected(1, 8);
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
    p.track.model_subsample = subsample;
    p.device = Device::cpu();
    Reconstruction loop(p, rig);
    const PinholeCamera cam = rig.depth_camera.subsampled(p.track.model_subsample);
    Raycaster raycaster(p.raycast);
    FrameHints frame_hints;
    RaycastResult previous;
    RaycastHints hints;
    Pose T_wc;
    RgbdFrame f;  // after the loop: frame `at`
    for (int i = 0; i <= at; ++i) {
      f = reader->read(static_cast<std::size_t>(i));
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
    report_levels(map);
    report_walk(view, f, rig, p);

    std::vector<float> z_lo, z_hi;
    const kernels::RangeTiles tiles = filled_tiles(map, cam, p.raycast.tuning.range_tile_px, T_wc,
                                                   p.fusion.depth_range, &z_lo, &z_hi);
    const Rigid3f T = to_rigid3f(T_wc);
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
    variants.push_back({"level-hints", variants.front().k, true, {}});

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
          if (v.level_hints && !previous.levels.empty()) r.hints.level = previous.levels(x, y);
          r.dir = T.rotate(cam.ray(static_cast<float>(x), static_cast<float>(y)));
        }
    }
    for (int round = 0; round < rounds; ++round)
      for (Variant& v : variants)
        for (Ray& r : v.rays) {
          kernels::BlockLookupCache cache;
          kernels::RayHit hit;
          const Clock::time_point t0 = Clock::now();
          r.outcome =
              kernels::cast_ray(view, cache, T.t, r.dir, r.hints, r.z_min, r.z_max, v.k, &hit);
          const double ns = std::chrono::duration<double, std::nano>(Clock::now() - t0).count();
          r.ns = std::min(r.ns, ns);
          // The search at the hints alone: what the ray costs a kernel that leaves its march
          // to another.
          kernels::BlockLookupCache hint_cache;
          kernels::RayHit hint_hit;
          const Clock::time_point t1 = Clock::now();
          kernels::search_at_hints(view, hint_cache, T.t, r.dir, r.hints, r.z_max, v.k, &hint_hit);
          r.hint_ns = std::min(r.hint_ns,
                               std::chrono::duration<double, std::nano>(Clock::now() - t1).count());
          r.lookups = cache.table_lookups;
          r.cross_level = cache.cross_level_cells;
          r.irregular = cache.irregular_cells;
          r.depth_m = hit.depth_m;
          r.level = r.outcome == kernels::RayOutcome::Miss ? -1 : hit.level;
        }
    for (const Variant& v : variants) report(v, cam, top);
    for (const double back_m : split_accuracy) {
      Pose from = T_wc;
      from.translate(Eigen::Vector3d(0.0, 0.0, -back_m));
      DepthRange range = p.fusion.depth_range;
      range.max_m += static_cast<float>(back_m);
      const std::string name = fmt::format("{:.2f} m back", back_m);
      report_split_accuracy(map, variants.front().k, cam, p.raycast.tuning.range_tile_px, from,
                            range, name.c_str());
    }
    if (!dump.empty()) {
      FILE* out = std::fopen(dump.c_str(), "w");
      if (out == nullptr) fail(ErrorCode::Io, "--dump {}: cannot be written", dump);
      for (const Ray& r : variants.back().rays)
        std::fprintf(out, "%d %.7f\n", static_cast<int>(r.outcome), r.depth_m);
      std::fclose(out);
    }
  } catch (const Error& e) {
    std::fprintf(stderr, "ray_cost: %s\n", e.what());
    return 1;
  }
  return 0;
}

#pragma once
// Shared by the raycast tests: the ray packets checked against the ray-by-ray search.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "hivox/core/image.h"
#include "hivox/raycast/raycaster.h"

namespace hivox::test {

// Hints as the pipeline passes them, and worse: the true depth with noise of up to a band,
// missing pixels, and pixels whose hint is far behind every surface.
inline DepthImage mixed_hints(const DepthImage& truth, float mu) {
  DepthImage hint = truth;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> offset(-mu, mu);
  std::uniform_int_distribution<int> kind(0, 9);
  for (std::size_t i = 0; i < hint.size(); ++i) {
    float& h = hint.data()[i];
    if (h <= 0.0f) continue;
    const int k = kind(rng);
    h = k == 0 ? 0.0f : (k == 1 ? h + 1.0f : h + offset(rng));
  }
  return hint;
}

// The packets are an evaluation order, not a method: every pixel comes out as the ray-by-ray
// search gives it, up to float rounding (the vectorized interpolation may fuse multiplies and
// adds where the scalar one does not), which can at most decide a sample's sign on a knife
// edge.
inline void expect_same_raycast(const RaycastResult& a, const RaycastResult& b, int min_hits,
                                const char* what = "packets vs ray by ray") {
  int hits = 0, differ = 0, pixels = 0;
  double max_depth = 0, max_normal = 0;
  for (int y = 0; y < a.depth_m.height(); ++y)
    for (int x = 0; x < a.depth_m.width(); ++x) {
      ++pixels;
      if (a.hit(x, y) != b.hit(x, y) || a.levels(x, y) != b.levels(x, y)) {
        ++differ;
        continue;
      }
      if (!a.hit(x, y)) continue;
      ++hits;
      max_depth = std::max(max_depth, double(std::abs(a.depth_m(x, y) - b.depth_m(x, y))));
      for (int k = 0; k < 3; ++k)
        max_normal =
            std::max(max_normal, double(std::abs(a.normals_w(x, y)[k] - b.normals_w(x, y)[k])));
    }
  EXPECT_GT(hits, min_hits);
  EXPECT_LE(differ, pixels / 2000) << "pixels hit by one and not the other";
  EXPECT_LT(max_depth, 1e-4) << "metres";  // rounding; the voxels are 4-10 mm
  EXPECT_LT(max_normal, 1e-3);
  std::printf(
      "%s: %d hits, %d pixels differ, depth within %.2g m, normals "
      "within %.2g\n",
      what, hits, differ, max_depth, max_normal);
}

/// Raycasts `map` from `T_wc` with `hint` (and `fallback`, optional) twice, with and without ray
/// packets, and checks the two results are identical.
inline void expect_packets_match(const VoxelBlockMap& map, RaycastParams rp,
                                 const PinholeCamera& cam, const Pose& T_wc, const DepthImage& hint,
                                 int min_hits, const DepthImage* fallback = nullptr,
                                 const DepthRange& range = {}) {
  rp.tuning.ray_packets = true;
  Raycaster packets(rp);
  rp.tuning.ray_packets = false;
  Raycaster one_by_one(rp);
  RaycastStats a, b;
  expect_same_raycast(packets.raycast(map, cam, T_wc, range, {&hint, fallback}, &a),
                      one_by_one.raycast(map, cam, T_wc, range, {&hint, fallback}, &b), min_hits);
  EXPECT_NEAR(a.found_at_fallback, b.found_at_fallback, 1 + a.found_at_fallback / 1000);
}

/// Raycasts `map` from `T_wc` (with `hint` and `fallback`, both optional) with and without the
/// surface tiles (RaycastTuning::surface_tiles), in packets and ray by ray: they only spare
/// marches over space where no surface can be, so every pixel must come out bit for bit the same.
inline void expect_surface_tiles_change_nothing(const VoxelBlockMap& map, RaycastParams rp,
                                                const PinholeCamera& cam, const Pose& T_wc,
                                                int min_hits, const DepthImage* hint = nullptr,
                                                const DepthImage* fallback = nullptr,
                                                const DepthRange& range = {}) {
  for (const bool packets : {true, false}) {
    rp.tuning.ray_packets = packets;
    rp.tuning.surface_tiles = SurfaceTileUse::Always;
    Raycaster with(rp);
    rp.tuning.surface_tiles = SurfaceTileUse::Never;
    Raycaster without(rp);
    RaycastStats sa, sb;
    const RaycastResult& a = with.raycast(map, cam, T_wc, range, {hint, fallback}, &sa);
    const RaycastResult& b = without.raycast(map, cam, T_wc, range, {hint, fallback}, &sb);
    int hits = 0, differ = 0;
    for (int y = 0; y < cam.height; ++y)
      for (int x = 0; x < cam.width; ++x) {
        hits += a.hit(x, y);
        const bool same = a.depth_m(x, y) == b.depth_m(x, y) && a.levels(x, y) == b.levels(x, y) &&
                          a.normals_w(x, y) == b.normals_w(x, y) &&
                          a.points_w(x, y) == b.points_w(x, y);
        differ += !same;
      }
    EXPECT_GT(hits, min_hits) << "packets " << packets;
    EXPECT_EQ(differ, 0) << "pixels that differ with and without the surface tiles, packets "
                         << packets;
    EXPECT_EQ(sa.found_at_hint, sb.found_at_hint) << "packets " << packets;
  }
}

}  // namespace hivox::test

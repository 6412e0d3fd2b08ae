#pragma once
// Per-pixel and per-voxel fusion math, written once for the CPU and CUDA drivers.

#include <cfloat>
#include <climits>
#include <cstdlib>

#include "hivox/core/camera.h"
#include "hivox/core/hd.h"
#include "hivox/core/image.h"
#include "hivox/core/math.h"
#include "hivox/map/map_view.h"

namespace hivox::kernels {

/// A depth frame as kernels see it.
struct DepthFrameView {
  ImageView<const float> depth_m;  ///< metres, 0 = invalid
  PinholeCamera camera;
  float min_depth_m = 0;
  float max_depth_m = 0;
  HIVOX_HD float valid_depth(int x, int y) const {
    const float d = depth_m(x, y);
    return (d >= min_depth_m && d <= max_depth_m) ? d : 0.0f;
  }
};

/// Colour as kernels see it: either registered to depth (same pixel) or a separate camera.
struct ColorFrameView {
  ImageView<const Rgb8> image;  ///< empty = no colour
  PinholeCamera camera;
  Rigid3f T_color_depth;   ///< depth-camera point -> colour-camera point
  bool registered = true;  ///< colour pixel (u, v) = depth pixel (u, v)
  /// When registered: the image as 32-bit words (r | g << 8 | b << 16), so that a row of voxels
  /// gathers colour like depth and vectorizes. Null otherwise.
  const uint32_t* packed = nullptr;
};

/// Packs an RGB pixel the way `ColorFrameView::packed` holds it.
HIVOX_HD inline uint32_t pack_rgb(const Rgb8& c) {
  return static_cast<uint32_t>(c.r) | (static_cast<uint32_t>(c.g) << 8) |
         (static_cast<uint32_t>(c.b) << 16);
}

// ---- allocation: blocks crossed by the truncation band of each ray ---------------------------

/// Integer box of block coordinates (inclusive) that a walk may visit.
struct BlockBounds {
  Vec3i lo{INT_MIN, INT_MIN, INT_MIN};
  Vec3i hi{INT_MAX, INT_MAX, INT_MAX};
  HIVOX_HD bool contains(const Vec3i& c) const {
    return c.x >= lo.x && c.y >= lo.y && c.z >= lo.z && c.x <= hi.x && c.y <= hi.y && c.z <= hi.z;
  }
  HIVOX_HD Vec3i clamp(const Vec3i& c) const {
    Vec3i r = c;
    for (int k = 0; k < 3; ++k) r[k] = r[k] < lo[k] ? lo[k] : (r[k] > hi[k] ? hi[k] : r[k]);
    return r;
  }
};

template <bool kUnbounded = false, typename Visitor>
HIVOX_HD void walk_segment_in(const MapView& map, int level, const Vec3f& a_w, const Vec3f& b_w,
                              const BlockBounds& bounds, Visitor& visitor);

/// Visits, in order, every block of `level` that segment a_w -> b_w passes through (3D DDA,
/// Amanatides & Woo) within `bounds`. `visitor.block(level, pos)` returns the block's `ptr`
/// (kPtrEmpty when absent); a Split block is walked again one level finer over the part of the
/// segment inside it, restricted to its 8 children, so every point is handled at exactly the
/// level that stores it.
template <typename Visitor>
HIVOX_HD void walk_segment_level(const MapView& map, int level, const Vec3f& a_w, const Vec3f& b_w,
                                 const BlockBounds& bounds, Visitor& visitor) {
  const float inv_block = map.level[level].inv_block_size;
  const Vec3f p = a_w * inv_block;
  const Vec3f d = (b_w - a_w) * inv_block;
  Vec3i cell = bounds.clamp(floor_to_int(p));
  const Vec3i last = bounds.clamp(floor_to_int(p + d));
  int step[3];
  float t_max[3], t_delta[3];
  for (int k = 0; k < 3; ++k) {
    if (d[k] > 0.0f) {
      step[k] = 1;
      t_delta[k] = 1.0f / d[k];
      t_max[k] = (static_cast<float>(cell[k]) + 1.0f - p[k]) * t_delta[k];
    } else if (d[k] < 0.0f) {
      step[k] = -1;
      t_delta[k] = -1.0f / d[k];
      t_max[k] = (p[k] - static_cast<float>(cell[k])) * t_delta[k];
    } else {
      step[k] = 0;
      t_delta[k] = FLT_MAX;
      t_max[k] = FLT_MAX;
    }
  }
  const int max_steps = abs(last.x - cell.x) + abs(last.y - cell.y) + abs(last.z - cell.z) + 1;
  float t_enter = 0.0f;
  for (int i = 0; i < max_steps; ++i) {
    const int axis =
        t_max[0] < t_max[1] ? (t_max[0] < t_max[2] ? 0 : 2) : (t_max[1] < t_max[2] ? 1 : 2);
    const float t_exit = t_max[axis] < 1.0f ? t_max[axis] : 1.0f;
    const int32_t ptr = visitor.block(level, cell);
    if (ptr == kPtrSplit && level > 0) {
      BlockBounds children;
      children.lo = {2 * cell.x, 2 * cell.y, 2 * cell.z};
      children.hi = {2 * cell.x + 1, 2 * cell.y + 1, 2 * cell.z + 1};
      walk_segment_in(map, level - 1, a_w + (b_w - a_w) * t_enter, a_w + (b_w - a_w) * t_exit,
                      children, visitor);
    }
    if (cell == last || t_max[axis] > 1.0f) break;
    t_enter = t_max[axis];
    cell[axis] += step[axis];
    t_max[axis] += t_delta[axis];
    if (!bounds.contains(cell)) break;
  }
}

/// Visits the blocks of `level` (within `bounds`) that segment a_w -> b_w passes through, and
/// below Split ones their children likewise. Most segments start and end in the same block or
/// in two blocks sharing a face (at every level: a band segment is short, and below a Split
/// block it is clipped to that block); those are visited directly -- the same blocks in the same
/// order as the DDA would give, without its set-up -- everything else takes the DDA.
/// `kUnbounded` (the coarsest level: `bounds` is everything) makes a separate, non-recursive
/// function that the per-pixel loop inlines.
template <bool kUnbounded, typename Visitor>
HIVOX_HD void walk_segment_in(const MapView& map, int level, const Vec3f& a_w, const Vec3f& b_w,
                              const BlockBounds& bounds, Visitor& visitor) {
  const LevelView& lv = map.level[level];
  const Vec3i cell_a = kUnbounded ? block_of_point(lv, a_w) : bounds.clamp(block_of_point(lv, a_w));
  const Vec3i cell_b = kUnbounded ? block_of_point(lv, b_w) : bounds.clamp(block_of_point(lv, b_w));
  const Vec3i diff{cell_b.x - cell_a.x, cell_b.y - cell_a.y, cell_b.z - cell_a.z};
  const int manhattan = abs(diff.x) + abs(diff.y) + abs(diff.z);
  if (manhattan > 1) {
    walk_segment_level(map, level, a_w, b_w, bounds, visitor);
    return;
  }
  const auto children_of = [](const Vec3i& c) {
    return BlockBounds{{2 * c.x, 2 * c.y, 2 * c.z}, {2 * c.x + 1, 2 * c.y + 1, 2 * c.z + 1}};
  };
  if (manhattan == 0) {
    if (visitor.block(level, cell_a) == kPtrSplit && level > 0)
      walk_segment_in(map, level - 1, a_w, b_w, children_of(cell_a), visitor);
    return;
  }
  // Two face neighbours: the segment crosses their common face once, at parameter t (only
  // needed below a Split one).
  const auto crossing = [&]() {
    const int axis = diff.x != 0 ? 0 : (diff.y != 0 ? 1 : 2);
    const int face = cell_a[axis] > cell_b[axis] ? cell_a[axis] : cell_b[axis];
    const float t =
        (static_cast<float>(face) * lv.block_size_m - a_w[axis]) / (b_w[axis] - a_w[axis]);
    return a_w + (b_w - a_w) * clampf(t, 0.0f, 1.0f);
  };
  if (visitor.block(level, cell_a) == kPtrSplit && level > 0)
    walk_segment_in(map, level - 1, a_w, crossing(), children_of(cell_a), visitor);
  if (visitor.block(level, cell_b) == kPtrSplit && level > 0)
    walk_segment_in(map, level - 1, crossing(), b_w, children_of(cell_b), visitor);
}

/// Walks the segment from the coarsest level down (see walk_segment_in).
template <typename Visitor>
HIVOX_HD void walk_segment(const MapView& map, const Vec3f& a_w, const Vec3f& b_w,
                           Visitor& visitor) {
  walk_segment_in<true>(map, map.levels - 1, a_w, b_w, BlockBounds{}, visitor);
}

/// The truncation-band segment of pixel (x, y) in world coordinates: depths [d - mu, d + mu]
/// along the pixel's ray. Returns false for an invalid pixel.
HIVOX_HD inline bool band_segment(const DepthFrameView& frame, const Rigid3f& T_wc, float mu_m,
                                  int x, int y, Vec3f* a_w, Vec3f* b_w) {
  const float d = frame.valid_depth(x, y);
  if (d <= 0.0f) return false;
  const Vec3f ray = frame.camera.ray(static_cast<float>(x), static_cast<float>(y));
  const float near = d - mu_m > 1e-3f ? d - mu_m : 1e-3f;
  *a_w = T_wc * (ray * near);
  *b_w = T_wc * (ray * (d + mu_m));
  return true;
}

// ---- integration: the per-voxel update ------------------------------------------------------

/// Running weighted average of the truncated signed distance (KinectFusion):
/// F <- (W F + f) / (W + 1), W <- min(W + 1, W_max), with f = min(1, eta / mu), eta >= -mu.
/// Works on the voxel's 32-bit word (int16 TSDF low, uint16 weight high) so that a row of
/// voxels vectorizes.
HIVOX_HD inline uint32_t fuse_tsdf_word(uint32_t word, float eta_m, float inv_mu, int max_weight) {
  const float f = clampf(eta_m * inv_mu, -1.0f, 1.0f);
  const int w = static_cast<int>(word >> 16);
  const float old_f = static_cast<float>(tsdf_of_word(word)) * (1.0f / kTsdfScale);
  const float fused = (old_f * static_cast<float>(w) + f) / static_cast<float>(w + 1);
  // Round half away from zero by truncation (vectorizes, unlike lrintf/floorf calls).
  const float scaled = clampf(fused, -1.0f, 1.0f) * kTsdfScale;
  const int fused_i = static_cast<int>(scaled + (scaled >= 0.0f ? 0.5f : -0.5f));
  const int new_w = w + 1 < max_weight ? w + 1 : max_weight;
  return (static_cast<uint32_t>(new_w) << 16) | (static_cast<uint32_t>(fused_i) & 0xFFFFu);
}

HIVOX_HD inline void fuse_tsdf(TsdfVoxel& v, float eta_m, float inv_mu, int max_weight) {
  const uint32_t word = (static_cast<uint32_t>(v.weight) << 16) | static_cast<uint16_t>(v.tsdf);
  const uint32_t fused = fuse_tsdf_word(word, eta_m, inv_mu, max_weight);
  v.tsdf = static_cast<int16_t>(fused & 0xFFFFu);
  v.weight = static_cast<uint16_t>(fused >> 16);
}

/// Running average of colour with its own weight (capped at min(W_max, 255)), on the voxel's
/// 32-bit word (r | g << 8 | b << 16 | weight << 24) so that a row of voxels vectorizes.
HIVOX_HD inline uint32_t fuse_color_word(uint32_t word, uint32_t rgb, int max_weight) {
  const int w = static_cast<int>(word >> 24);
  const float wf = static_cast<float>(w);
  const float inv = 1.0f / (wf + 1.0f);
  const uint32_t r = static_cast<uint32_t>(
      (static_cast<float>(word & 0xFFu) * wf + static_cast<float>(rgb & 0xFFu)) * inv + 0.5f);
  const uint32_t g = static_cast<uint32_t>(
      (static_cast<float>((word >> 8) & 0xFFu) * wf + static_cast<float>((rgb >> 8) & 0xFFu)) *
          inv +
      0.5f);
  const uint32_t b = static_cast<uint32_t>(
      (static_cast<float>((word >> 16) & 0xFFu) * wf + static_cast<float>((rgb >> 16) & 0xFFu)) *
          inv +
      0.5f);
  const int cap = max_weight < 255 ? max_weight : 255;
  const uint32_t new_w = static_cast<uint32_t>(w + 1 < cap ? w + 1 : cap);
  return r | (g << 8) | (b << 16) | (new_w << 24);
}

HIVOX_HD inline void fuse_color(ColorVoxel& c, const Rgb8& rgb, int max_weight) {
  const uint32_t word = static_cast<uint32_t>(c.r) | (static_cast<uint32_t>(c.g) << 8) |
                        (static_cast<uint32_t>(c.b) << 16) |
                        (static_cast<uint32_t>(c.weight) << 24);
  const uint32_t fused = fuse_color_word(word, pack_rgb(rgb), max_weight);
  c = {static_cast<uint8_t>(fused & 0xFFu), static_cast<uint8_t>((fused >> 8) & 0xFFu),
       static_cast<uint8_t>((fused >> 16) & 0xFFu), static_cast<uint8_t>(fused >> 24)};
}

struct IntegrationConstants {
  Rigid3f T_cw;  ///< world -> depth camera
  float mu_m = 0;
  float inv_mu = 0;
  int max_weight = 0;
  bool bilinear_depth = false;  ///< `DepthSampling::Bilinear`
};

/// Nearest pixel of continuous pixel coordinates `uv` (`PinholeCamera::project`) of a point at
/// depth `z_m`: `*index` is always a valid pixel index (clamped to the image), the return value
/// says whether the point really projects inside the image (and lies in front of the camera).
/// Branch-free, so that a row of voxels vectorizes.
HIVOX_HD inline bool nearest_pixel(const PinholeCamera& cam, Vec2f uv, float z_m, int* index) {
  const float u = uv.x + 0.5f, v = uv.y + 0.5f;
  const float w = static_cast<float>(cam.width), h = static_cast<float>(cam.height);
  const float last_u = w - 1.0f, last_v = h - 1.0f;
  // Non-short-circuit '&' and compare-and-select (not fminf/fmaxf, whose NaN rules block
  // vectorization) keep this free of branches.
  const bool inside = (z_m > 0.0f) & (u >= 0.0f) & (v >= 0.0f) & (u < w) & (v < h);
  float uc = u > 0.0f ? u : 0.0f;
  float vc = v > 0.0f ? v : 0.0f;
  uc = uc < last_u ? uc : last_u;
  vc = vc < last_v ? vc : last_v;
  *index = static_cast<int>(vc) * cam.width + static_cast<int>(uc);
  return inside;
}

/// `nearest_pixel` of a camera-frame point.
HIVOX_HD inline bool project_to_pixel(const PinholeCamera& cam, Vec3f p_c, int* index) {
  return nearest_pixel(cam, cam.project(p_c), p_c.z, index);
}

/// Depth at continuous pixel coordinates `uv` interpolated bilinearly between the 4 pixels
/// around them, where all 4 are valid (>= `min_depth_m`) and within `max_step_m` of each other;
/// the nearest pixel's depth otherwise (a depth edge must not blend foreground and background).
/// Branch-free (arithmetic blends), so that a row of voxels vectorizes.
HIVOX_HD inline float depth_bilinear(const PinholeCamera& cam, const float* depth_m, Vec2f uv,
                                     float min_depth_m, float max_step_m) {
  // Clamped so that the 2x2 neighbourhood stays inside the image (the caller tests whether the
  // point projects inside at all).
  const float last_u = static_cast<float>(cam.width) - 1.001f;
  const float last_v = static_cast<float>(cam.height) - 1.001f;
  float u = uv.x > 0.0f ? uv.x : 0.0f;
  float v = uv.y > 0.0f ? uv.y : 0.0f;
  u = u < last_u ? u : last_u;
  v = v < last_v ? v : last_v;
  const int iu = static_cast<int>(u), iv = static_cast<int>(v);
  const float fu = u - static_cast<float>(iu), fv = v - static_cast<float>(iv);
  const int i00 = iv * cam.width + iu;
  // Each pair of horizontal neighbours in one 64-bit load: half as many gathered elements. The
  // low half is the left pixel (little-endian, as on every target).
  uint64_t top_pair, bottom_pair;
  __builtin_memcpy(&top_pair, depth_m + i00, sizeof top_pair);
  __builtin_memcpy(&bottom_pair, depth_m + i00 + cam.width, sizeof bottom_pair);
  const uint32_t bits[4] = {static_cast<uint32_t>(top_pair), static_cast<uint32_t>(top_pair >> 32),
                            static_cast<uint32_t>(bottom_pair),
                            static_cast<uint32_t>(bottom_pair >> 32)};
  float d00, d10, d01, d11;
  __builtin_memcpy(&d00, &bits[0], sizeof d00);
  __builtin_memcpy(&d10, &bits[1], sizeof d10);
  __builtin_memcpy(&d01, &bits[2], sizeof d01);
  __builtin_memcpy(&d11, &bits[3], sizeof d11);
  float lo = d00 < d10 ? d00 : d10, hi = d00 > d10 ? d00 : d10;
  lo = d01 < lo ? d01 : lo;
  hi = d01 > hi ? d01 : hi;
  lo = d11 < lo ? d11 : lo;
  hi = d11 > hi ? d11 : hi;
  const float top = d00 + (d10 - d00) * fu, bottom = d01 + (d11 - d01) * fu;
  const float bilinear = top + (bottom - top) * fv;
  // The nearest of the 4 pixels, chosen arithmetically (a fifth gather costs more).
  const float left = fv < 0.5f ? d00 : d01, right = fv < 0.5f ? d10 : d11;
  const float nearest = fu < 0.5f ? left : right;
  const float smooth = static_cast<float>((lo >= min_depth_m) & (hi - lo <= max_step_m));
  return nearest + (bilinear - nearest) * smooth;
}

/// `integrate_block` for one way of sampling the depth image. The voxels are taken a z-slice
/// (64 voxels, contiguous in memory) at a time, so that the loops fill the widest vectors.
template <bool kBilinearDepth>
HIVOX_HD inline void integrate_block_slices(const MutableMapView& map, int level, const Vec3i& pos,
                                            int32_t ptr, const DepthFrameView& depth,
                                            const ColorFrameView& color,
                                            const IntegrationConstants& k) {
  constexpr int kSlice = kBlockSide * kBlockSide;
  const float s = map.read.level[level].voxel_size_m;
  const Vec3f origin_w = to_float(pos) * (static_cast<float>(kBlockSide) * s);
  const Vec3f origin_c = k.T_cw * origin_w;
  const Vec3f step_x = k.T_cw.R.col(0) * s;
  const Vec3f step_y = k.T_cw.R.col(1) * s;
  const Vec3f step_z = k.T_cw.R.col(2) * s;
  TsdfVoxel* voxels = map.tsdf + static_cast<int64_t>(ptr) * kBlockVoxels;
  ColorVoxel* colors = (map.color != nullptr && !color.image.empty())
                           ? map.color + static_cast<int64_t>(ptr) * kBlockVoxels
                           : nullptr;
  const float* depth_m = depth.depth_m.data;
  const float min_d = depth.min_depth_m, max_d = depth.max_depth_m;
  // The block's surface summary (BlockSurface): the octants whose cells have observed corners
  // and observed corners with TSDF <= 0 (voxel_octants; the slice's voxel i has x = i % 8 and
  // y = i / 8).
  uint32_t observed_octants = 0, surface_octants = 0;
  for (int z = 0; z < kBlockSide; ++z) {
    const float zf = static_cast<float>(z);
    // The camera-frame position of voxel i of the slice (x = i % 8, y = i / 8).
    auto voxel_c = [&](int i) {
      const float xf = static_cast<float>(i & (kBlockSide - 1));
      const float yf = static_cast<float>(i / kBlockSide);
      return Vec3f{origin_c.x + step_y.x * yf + step_z.x * zf + step_x.x * xf,
                   origin_c.y + step_y.y * yf + step_z.y * zf + step_x.y * xf,
                   origin_c.z + step_y.z * yf + step_z.z * zf + step_x.z * xf};
    };
    // The voxel's TSDF and weight as one 32-bit word (layout checked in voxel.h).
    uint32_t* out = reinterpret_cast<uint32_t*>(voxels + voxel_index(0, 0, z));
    int pixel[kSlice];           // depth pixel of observed voxels, -1 otherwise
    int any_pixel[kSlice];       // always a valid pixel index (branch-free gathers)
    uint32_t near_mask[kSlice];  // all ones where colour is fused (observed, near surface)
    float eta[kSlice];
    int summary[kSlice];  // the voxel's TSDF after the update, INT_MAX where unobserved
    [[maybe_unused]] float interpolated[kSlice];
    [[maybe_unused]] int projected[kSlice];
    [[maybe_unused]] uint32_t inside_word[kSlice];
    if constexpr (kBilinearDepth) {
      // A loop of its own: folded into the loop below, it keeps that loop from vectorizing.
      for (int i = 0; i < kSlice; ++i) {
        const Vec3f p = voxel_c(i);
        const Vec2f uv = depth.camera.project(p);
        inside_word[i] = nearest_pixel(depth.camera, uv, p.z, &projected[i]);
        interpolated[i] = depth_bilinear(depth.camera, depth_m, uv, min_d, k.mu_m);
      }
    }
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC ivdep
#endif
    for (int i = 0; i < kSlice; ++i) {
      const Vec3f p = voxel_c(i);
      int px;
      bool inside;
      float d;
      if constexpr (kBilinearDepth) {
        px = projected[i];
        inside = inside_word[i] != 0u;
        d = interpolated[i];
      } else {
        inside = project_to_pixel(depth.camera, p, &px);
        d = depth_m[px];
      }
      const bool observed = inside & (d >= min_d) & (d <= max_d) & (d - p.z >= -k.mu_m);
      eta[i] = d - p.z;
      const uint32_t word = out[i];
      const uint32_t fused = fuse_tsdf_word(word, eta[i], k.inv_mu, k.max_weight);
      // Selects written as bit operations: a ternary lets the compiler sink the update into
      // a branch, which blocks vectorization.
      const uint32_t keep = static_cast<uint32_t>(observed) - 1u;  // all ones when unobserved
      const uint32_t result = (fused & ~keep) | (word & keep);
      out[i] = result;
      pixel[i] = px | static_cast<int>(keep);
      any_pixel[i] = px;
      near_mask[i] = 0u - static_cast<uint32_t>(observed & (eta[i] < k.mu_m));
      summary[i] = (result >> 16) != 0u ? tsdf_of_word(result) : INT_MAX;
    }
    // A loop of its own: in the loop above, GCC narrows the octant masks to bytes and then
    // cannot vectorize the floats.
    uint32_t slice_observed = 0, slice_surface = 0;
    for (int i = 0; i < kSlice; ++i) {
      const uint32_t octants = voxel_octants(i & 7, i >> 3, z);
      slice_observed |= octants & (0u - static_cast<uint32_t>(summary[i] != INT_MAX));
      slice_surface |= octants & (0u - static_cast<uint32_t>(summary[i] <= 0));
    }
    observed_octants |= slice_observed;
    surface_octants |= slice_surface;
    if (colors == nullptr) continue;
    if (color.packed != nullptr) {  // registered colour: the same pixel, vectorized
      uint32_t* out_c = reinterpret_cast<uint32_t*>(colors + voxel_index(0, 0, z));
      const uint32_t* packed = color.packed;
      // Voxels and image never overlap: say so, or the gather blocks vectorization.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC ivdep
#endif
      for (int i = 0; i < kSlice; ++i) {
        const uint32_t word = out_c[i];
        const uint32_t fused = fuse_color_word(word, packed[any_pixel[i]], k.max_weight);
        out_c[i] = (fused & near_mask[i]) | (word & ~near_mask[i]);
      }
      continue;
    }
    for (int i = 0; i < kSlice; ++i) {
      if (pixel[i] < 0 || eta[i] >= k.mu_m) continue;  // colour only near the surface
      int c = pixel[i];
      if (!color.registered) {
        if (!project_to_pixel(color.camera, color.T_color_depth * voxel_c(i), &c)) continue;
      }
      fuse_color(colors[voxel_index(0, 0, z) + i], color.image.data[c], k.max_weight);
    }
  }
  BlockMeta& meta = map.meta[ptr];
  meta.surface.observed = static_cast<uint8_t>(observed_octants);
  meta.surface.surface = static_cast<uint8_t>(surface_octants);
  if (meta.updates < 65535) ++meta.updates;
}

/// Integrates one depth (and colour) frame into every voxel of one block, at the block's own
/// voxel size: project the voxel into the depth image; where a valid depth d (nearest pixel, or
/// bilinear when `k.bilinear_depth`) lies at or beyond z - mu, fuse the truncated distance
/// eta = d - z.
HIVOX_HD inline void integrate_block(const MutableMapView& map, int level, const Vec3i& pos,
                                     int32_t ptr, const DepthFrameView& depth,
                                     const ColorFrameView& color, const IntegrationConstants& k) {
  if (k.bilinear_depth)
    integrate_block_slices<true>(map, level, pos, ptr, depth, color, k);
  else
    integrate_block_slices<false>(map, level, pos, ptr, depth, color, k);
}

}  // namespace hivox::kernels

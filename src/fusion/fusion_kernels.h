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
};

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

/// Visits, in order, every block of `level` that segment a_w -> b_w passes through (3D DDA,
/// Amanatides & Woo) within `bounds`. `visitor.block(level, pos)` returns the block's `ptr`
/// (kPtrEmpty when absent); a Split block is walked again one level finer over the part of the
/// segment inside it, restricted to its 8 children, so every point is handled at exactly the
/// level that stores it.
template <typename Visitor>
HIVOX_HD void walk_segment_level(const MapView& map, int level, const Vec3f& a_w, const Vec3f& b_w,
                                 const BlockBounds& bounds, Visitor& visitor) {
  const float inv_block = 1.0f / map.level[level].block_size_m;
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
      walk_segment_level(map, level - 1, a_w + (b_w - a_w) * t_enter, a_w + (b_w - a_w) * t_exit,
                         children, visitor);
    }
    if (cell == last || t_max[axis] > 1.0f) break;
    t_enter = t_max[axis];
    cell[axis] += step[axis];
    t_max[axis] += t_delta[axis];
    if (!bounds.contains(cell)) break;
  }
}

/// Walks the segment from the coarsest level down.
template <typename Visitor>
HIVOX_HD void walk_segment(const MapView& map, const Vec3f& a_w, const Vec3f& b_w,
                           Visitor& visitor) {
  walk_segment_level(map, map.levels - 1, a_w, b_w, BlockBounds{}, visitor);
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
HIVOX_HD inline void fuse_tsdf(TsdfVoxel& v, float eta_m, float inv_mu, int max_weight) {
  const float f = fminf(1.0f, eta_m * inv_mu);
  const int w = v.weight;
  const float fused =
      (tsdf_to_float(v.tsdf) * static_cast<float>(w) + f) / static_cast<float>(w + 1);
  v.tsdf = tsdf_from_float(fused);
  v.weight = static_cast<uint16_t>(w + 1 < max_weight ? w + 1 : max_weight);
}

HIVOX_HD inline void fuse_color(ColorVoxel& c, const Rgb8& rgb, int max_weight) {
  const float w = static_cast<float>(c.weight);
  const float inv = 1.0f / (w + 1.0f);
  c.r = static_cast<uint8_t>((c.r * w + rgb.r) * inv + 0.5f);
  c.g = static_cast<uint8_t>((c.g * w + rgb.g) * inv + 0.5f);
  c.b = static_cast<uint8_t>((c.b * w + rgb.b) * inv + 0.5f);
  const int cap = max_weight < 255 ? max_weight : 255;
  c.weight = static_cast<uint8_t>(c.weight + 1 < cap ? c.weight + 1 : cap);
}

/// Nearest pixel of continuous coordinates (u, v), or false when outside the image.
HIVOX_HD inline bool nearest_pixel(float u, float v, int width, int height, int* x, int* y) {
  if (!(u >= -0.5f && v >= -0.5f && u < static_cast<float>(width) - 0.5f &&
        v < static_cast<float>(height) - 0.5f))
    return false;
  *x = static_cast<int>(u + 0.5f);
  *y = static_cast<int>(v + 0.5f);
  return true;
}

struct IntegrationConstants {
  Rigid3f T_cw;  ///< world -> depth camera
  float mu_m = 0;
  float inv_mu = 0;
  int max_weight = 0;
};

/// Integrates one depth (and colour) frame into every voxel of one block, at the block's own
/// voxel size: project the voxel into the depth image; where a valid depth d lies at or beyond
/// z - mu, fuse the truncated distance eta = d - z.
HIVOX_HD inline void integrate_block(const MapView& map, int level, const Vec3i& pos, int32_t ptr,
                                     const DepthFrameView& depth, const ColorFrameView& color,
                                     const IntegrationConstants& k) {
  const float s = map.level[level].voxel_size_m;
  const Vec3f origin_w = to_float(pos) * (static_cast<float>(kBlockSide) * s);
  const Vec3f origin_c = k.T_cw * origin_w;
  const Vec3f step_x = k.T_cw.R.col(0) * s;
  const Vec3f step_y = k.T_cw.R.col(1) * s;
  const Vec3f step_z = k.T_cw.R.col(2) * s;
  TsdfVoxel* voxels = map.tsdf + static_cast<int64_t>(ptr) * kBlockVoxels;
  ColorVoxel* colors = (map.color != nullptr && !color.image.empty())
                           ? map.color + static_cast<int64_t>(ptr) * kBlockVoxels
                           : nullptr;
  const PinholeCamera& cam = depth.camera;
  for (int z = 0; z < kBlockSide; ++z) {
    for (int y = 0; y < kBlockSide; ++y) {
      Vec3f p = origin_c + step_y * static_cast<float>(y) + step_z * static_cast<float>(z);
      for (int x = 0; x < kBlockSide; ++x, p += step_x) {
        if (p.z <= 0.0f) continue;
        const float inv_z = 1.0f / p.z;
        int px, py;
        if (!nearest_pixel(cam.fx * p.x * inv_z + cam.cx, cam.fy * p.y * inv_z + cam.cy, cam.width,
                           cam.height, &px, &py))
          continue;
        const float d = depth.valid_depth(px, py);
        if (d <= 0.0f) continue;
        const float eta = d - p.z;
        if (eta < -k.mu_m) continue;
        const int i = voxel_index(x, y, z);
        fuse_tsdf(voxels[i], eta, k.inv_mu, k.max_weight);
        if (colors != nullptr && eta < k.mu_m) {
          int cx = px, cy = py;
          bool inside = true;
          if (!color.registered) {
            const Vec3f q = color.T_color_depth * p;
            inside =
                q.z > 0.0f && nearest_pixel(color.camera.project(q).x, color.camera.project(q).y,
                                            color.image.width, color.image.height, &cx, &cy);
          }
          if (inside) fuse_color(colors[i], color.image(cx, cy), k.max_weight);
        }
      }
    }
  }
}

}  // namespace hivox::kernels

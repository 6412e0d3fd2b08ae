#pragma once
// The forward warp of a raycast's surface into another view (warp_raycast_depth), per element:
// written once for the CPU and CUDA drivers. A hit lands on its nearest pixel (warp_landing),
// the nearest landing wins, then a pixel keeps its depth or fills a hole from its neighbours
// (warp_hole), unless a nearer surface may show through (warp_keep).

#include <cfloat>

#include "hivox/core/camera.h"
#include "hivox/core/hd.h"
#include "hivox/core/math.h"

namespace hivox::kernels {

/// The view a raycast is warped into: its pose and pinhole, and the gap rule's limit.
struct WarpView {
  Rigid3f T_cw;
  float fx = 0, fy = 0, cx = 0, cy = 0;
  int width = 0, height = 0;
  float max_gap_m = 0;

  /// `camera` seen from pose `T_cw` (world to camera).
  static WarpView of(const Rigid3f& T_cw, const PinholeCamera& camera, float max_gap_m) {
    return {T_cw,      camera.fx,    camera.fy,     camera.cx,
            camera.cy, camera.width, camera.height, max_gap_m};
  }
};

/// Where hit `p_w` (normal `n_w`; `depth` its raycast depth, 0: no hit) lands: the pixel
/// (`*u`, `*v`, floor of the coordinate + 1/2) and the depth at that pixel's centre on the hit's
/// tangent plane, at most half the gap from the hit's own depth (an oblique surface's own depth
/// is off by up to a voxel or more half a pixel away; grazing planes are clamped). Returns 0
/// where it lands nowhere (no hit, behind the camera, outside the image). Branch-free, so that
/// a CPU loop over a row of hits vectorizes.
HIVOX_HD HIVOX_FORCEINLINE float warp_landing(const WarpView& w, float depth, const Vec3f& p_w,
                                              const Vec3f& n_w, float* u, float* v) {
  const Vec3f p = w.T_cw * p_w;
  const float inv_z = 1.0f / p.z;
  const float u_half = w.fx * p.x * inv_z + w.cx + 0.5f;
  const float v_half = w.fy * p.y * inv_z + w.cy + 0.5f;
  const float uf = floor_nonnegative(u_half), vf = floor_nonnegative(v_half);
  const bool lands = (depth > 0.0f) & (p.z > 0.0f) & (u_half >= 0.0f) & (v_half >= 0.0f) &
                     (u_half < static_cast<float>(w.width)) &
                     (v_half < static_cast<float>(w.height));
  *u = uf;
  *v = vf;
  const Vec3f n = w.T_cw.rotate(n_w);
  const Vec3f ray{(uf - w.cx) / w.fx, (vf - w.cy) / w.fy, 1.0f};
  const float n_ray = dot(n, ray);
  const bool oblique = fabsf(n_ray) > 1e-6f;  // else the hit's own depth
  const float z = oblique ? dot(n, p) / (oblique ? n_ray : 1.0f) : p.z;
  const float limit = 0.5f * w.max_gap_m;
  const float z_lo = p.z - limit, z_hi = p.z + limit;
  return lands ? (z < z_lo ? z_lo : (z > z_hi ? z_hi : z)) : 0.0f;
}

/// The depth a pixel no hit landed on takes from its neighbours: `landed(u, v)` gives the nearest
/// depth landed on pixel (u, v) (FLT_MAX: none, or outside the image). The nearer of two
/// opposite neighbours' depths (left and right, up and down, or diagonal) that agree within the
/// gap: the new view magnifies the surface, or its pixels sample it elsewhere. A pixel beside a
/// silhouette has hits on one side only and stays empty (FLT_MAX).
template <typename Landed>
HIVOX_HD inline float warp_hole(const Landed& landed, int x, int y, float max_gap_m) {
  constexpr int kOpposite[4][2] = {{1, 0}, {0, 1}, {1, 1}, {1, -1}};
  float z = FLT_MAX;
  for (const auto& d : kOpposite) {
    const float a = landed(x - d[0], y - d[1]), b = landed(x + d[0], y + d[1]);
    if (a < FLT_MAX && b < FLT_MAX && fabsf(a - b) <= max_gap_m) {
      const float m = a < b ? a : b;
      z = m < z ? m : z;
    }
  }
  return z;
}

/// A pixel's warped depth `z` (FLT_MAX: none) given `front`, the nearest depth landed within one
/// pixel of it: dropped (0) where that surface lies nearer by more than the gap (a surface that
/// may show through a gap in the warped foreground).
HIVOX_HD inline float warp_keep(float z, float front, float max_gap_m) {
  return z < FLT_MAX && z - front <= max_gap_m ? z : 0.0f;
}

}  // namespace hivox::kernels

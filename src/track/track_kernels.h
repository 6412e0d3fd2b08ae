#pragma once
// Per-pixel tracking math, written once for host and device: bilateral filter, normals from a
// point image, robust weights, point-to-plane residuals and their Jacobians.

#include <cmath>

#include "hivox/core/hd.h"
#include "hivox/core/image.h"
#include "hivox/core/math.h"
#include "hivox/track/params.h"

namespace hivox::kernels {

/// Weight of a neighbour `dist2_px` squared pixels away whose depth differs by `dd_m` in the
/// bilateral filter.
HIVOX_HD inline float bilateral_weight(float dist2_px, float dd_m, float inv_2sigma_px2,
                                       float inv_2sigma_d2) {
  return exp_nonpositive(-dist2_px * inv_2sigma_px2 - dd_m * dd_m * inv_2sigma_d2);
}

/// Bilateral-filtered depth at (x, y); 0 where the input is invalid or outside [min, max].
HIVOX_HD inline float bilateral_depth(ImageView<const float> in, int x, int y, int radius,
                                      float inv_2sigma_px2, float inv_2sigma_d2, float min_m,
                                      float max_m) {
  const float d0 = in(x, y);
  if (!(d0 >= min_m && d0 <= max_m)) return 0.0f;
  float sum = 0.0f, wsum = 0.0f;
  for (int dy = -radius; dy <= radius; ++dy) {
    const int yy = y + dy;
    if (yy < 0 || yy >= in.height) continue;
    for (int dx = -radius; dx <= radius; ++dx) {
      const int xx = x + dx;
      if (xx < 0 || xx >= in.width) continue;
      const float d = in(xx, yy);
      if (!(d >= min_m && d <= max_m)) continue;
      const float w = bilateral_weight(static_cast<float>(dx * dx + dy * dy), d - d0,
                                       inv_2sigma_px2, inv_2sigma_d2);
      sum += w * d;
      wsum += w;
    }
  }
  return sum / wsum;  // wsum >= 1: the centre pixel counts
}

/// The zero vector marks "no normal" in normal images.
HIVOX_HD inline bool is_zero(const Vec3f& v) {
  return v.x == 0.0f && v.y == 0.0f && v.z == 0.0f;
}

/// Whether depths a and b (both valid) lie on one surface.
HIVOX_HD inline bool same_surface(float a, float b, float max_jump_ratio) {
  return b > 0.0f && fabsf(a - b) <= max_jump_ratio * a;
}

/// The samples of a 2x2 block (depth <= 0: none) that lie on the surface of its first valid
/// one, as a bit mask: what downsampling averages, so that no average mixes two surfaces.
HIVOX_HD inline int same_surface_2x2(const float d[4], float max_jump_ratio) {
  int mask = 0;
  float first = 0.0f;
  for (int k = 0; k < 4; ++k) {
    if (d[k] <= 0.0f) continue;
    if (mask == 0) first = d[k];
    if (same_surface(first, d[k], max_jump_ratio)) mask |= 1 << k;
  }
  return mask;
}

/// Unit normal at (x, y) from central differences of the point image, pointing to the camera
/// (the origin); zero at borders, without depth, or across a depth discontinuity.
HIVOX_HD inline Vec3f normal_from_points(ImageView<const Vec3f> p, int x, int y,
                                         float max_jump_ratio) {
  const Vec3f zero{0, 0, 0};
  if (x < 1 || y < 1 || x + 1 >= p.width || y + 1 >= p.height) return zero;
  const Vec3f c = p(x, y);
  if (c.z <= 0.0f) return zero;
  const Vec3f l = p(x - 1, y), r = p(x + 1, y), u = p(x, y - 1), d = p(x, y + 1);
  if (!same_surface(c.z, l.z, max_jump_ratio) || !same_surface(c.z, r.z, max_jump_ratio) ||
      !same_surface(c.z, u.z, max_jump_ratio) || !same_surface(c.z, d.z, max_jump_ratio))
    return zero;
  Vec3f n = normalized(cross(r - l, d - u));
  if (dot(n, c) > 0.0f) n = -n;
  return n;
}

/// Weight of a residual `r_sigmas` (in units of its sigma) under `loss` with threshold `k`.
HIVOX_HD inline float robust_weight(float r_sigmas, RobustLoss loss, float k) {
  const float a = fabsf(r_sigmas);
  switch (loss) {
    case RobustLoss::None:
      return 1.0f;
    case RobustLoss::Huber:
      return a <= k ? 1.0f : k / a;
    case RobustLoss::Tukey: {
      if (a >= k) return 0.0f;
      const float t = 1.0f - (a / k) * (a / k);
      return t * t;
    }
  }
  return 1.0f;
}

/// Point-to-plane residual of frame point `p_w` against model point `q_w` with normal `n_w`,
/// and its derivative with respect to a small world-frame motion (t, w) of the camera about its
/// centre `c_w` (p -> p + w x (p - c) + t): J = [n, (p - c) x n]. Rotating about the camera
/// keeps the system well conditioned wherever the world origin is.
HIVOX_HD inline float point_to_plane(const Vec3f& p_w, const Vec3f& q_w, const Vec3f& n_w,
                                     const Vec3f& c_w, float J[6]) {
  const Vec3f pxn = cross(p_w - c_w, n_w);
  J[0] = n_w.x;
  J[1] = n_w.y;
  J[2] = n_w.z;
  J[3] = pxn.x;
  J[4] = pxn.y;
  J[5] = pxn.z;
  return dot(n_w, p_w - q_w);
}

}  // namespace hivox::kernels

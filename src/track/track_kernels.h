#pragma once
// Per-pixel tracking math, written once for host and device: bilateral filter, normals from a
// point image, robust weights, point-to-plane residuals and their Jacobians.

#include <cmath>
#include <numbers>

#include "hivox/core/camera.h"
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

/// The zero vector marks "no normal" in normal images. (Without short-circuits: loops over it
/// vectorize.)
HIVOX_HD inline bool is_zero(const Vec3f& v) {
  return (v.x == 0.0f) & (v.y == 0.0f) & (v.z == 0.0f);
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
/// Every loss's weight is computed (each finite) and one kept by multiplying with 0 or 1:
/// straight-line code, so that loops over pixels vectorize (GCC does not vectorize a choice
/// between their values made by the loss).
HIVOX_HD inline float robust_weight(float r_sigmas, RobustLoss loss, float k) {
  const float a = fabsf(r_sigmas);
  const float huber = a <= k ? 1.0f : k / a;
  const float t = 1.0f - (a / k) * (a / k);
  const float tukey = a >= k ? 0.0f : t * t;
  const float is_huber = loss == RobustLoss::Huber ? 1.0f : 0.0f;
  const float is_tukey = loss == RobustLoss::Tukey ? 1.0f : 0.0f;
  return is_huber * huber + is_tukey * tukey + (1.0f - is_huber - is_tukey);
}

/// The derivative of a point-to-plane residual with respect to a small world-frame motion
/// (t, w) of the camera: [d/dt, d/dw].
struct PlaneJacobian {
  Vec3f t, w;
};

/// Point-to-plane residual of frame point `p_w` against model point `q_w` with normal `n_w`,
/// and its derivative with respect to a small world-frame motion (t, w) of the camera about its
/// centre `c_w` (p -> p + w x (p - c) + t): J = [n, (p - c) x n]. Rotating about the camera
/// keeps the system well conditioned wherever the world origin is.
HIVOX_HD inline float point_to_plane(const Vec3f& p_w, const Vec3f& q_w, const Vec3f& n_w,
                                     const Vec3f& c_w, PlaneJacobian* J) {
  J->t = Vec3f{n_w.x, n_w.y, n_w.z};  // (a copy of the whole vector keeps loops scalar)
  J->w = cross(p_w - c_w, n_w);
  return dot(n_w, p_w - q_w);
}

/// What one pass of projective association at a pose needs (ICP), in plain fields: loops over
/// pixels that read the fields of the camera and pose objects themselves do not vectorize.
struct IcpPass {
  Rigid3f T_wc;                          ///< the frame's pose being refined
  Rigid3f T_model_cw;                    ///< world to the model's camera
  float fx = 0, fy = 0, cx = 0, cy = 0;  ///< the model's camera
  int width = 0, height = 0;
  float max_distance2_m2 = 0;  ///< squared distance beyond which a pair is rejected
  float cos_max_angle = 0;     ///< normals less aligned than this are rejected
  float residual_floor2_m2 = 0;
  float robust_scale = 0;
  RobustLoss loss = RobustLoss::Huber;
  SensorNoise noise;

  IcpPass(const Rigid3f& T_wc_, const Rigid3f& T_model_cw_, const PinholeCamera& model,
          float max_distance_m, const TrackParams& p)
      : T_wc(T_wc_),
        T_model_cw(T_model_cw_),
        fx(model.fx),
        fy(model.fy),
        cx(model.cx),
        cy(model.cy),
        width(model.width),
        height(model.height),
        max_distance2_m2(max_distance_m * max_distance_m),
        cos_max_angle(std::cos(p.max_normal_angle_deg * std::numbers::pi_v<float> / 180.0f)),
        residual_floor2_m2(p.residual_floor_m * p.residual_floor_m),
        robust_scale(p.robust_scale),
        loss(p.loss),
        noise(p.noise) {}
};

/// The model pixel nearest to where world point `p_w` projects in the model's camera, as an
/// index into its row-major images; false (and index 0, so that reads stay in the image) where
/// the point lies behind the camera or projects outside the image.
HIVOX_HD inline bool icp_model_pixel(const IcpPass& c, const Vec3f& p_w, int32_t* index) {
  const Vec3f p_m = c.T_model_cw * p_w;
  const bool in_front = p_m.z > 0.0f;
  const float inv_z = 1.0f / (in_front ? p_m.z : 1.0f);
  // floor(coordinate + 1/2)
  const float u_half = (c.fx * p_m.x * inv_z + c.cx) + 0.5f;
  const float v_half = (c.fy * p_m.y * inv_z + c.cy) + 0.5f;
  const bool inside = in_front & (u_half >= 0.0f) & (v_half >= 0.0f) &
                      (u_half < static_cast<float>(c.width)) &
                      (v_half < static_cast<float>(c.height));
  const int u = static_cast<int>(floor_nonnegative(inside ? u_half : 0.0f));
  const int v = static_cast<int>(floor_nonnegative(inside ? v_half : 0.0f));
  *index = v * c.width + u;
  return inside;
}

/// One frame pixel's term of the point-to-plane normal equations (see icp_pair_term).
struct IcpTerm {
  bool paired = false;  ///< false: no pair, the other fields mean nothing
  PlaneJacobian J;
  float r = 0;            ///< point-to-plane residual (metres)
  float sqrt_weight = 0;  ///< square root of the pair's weight
  float distance_m = 0;   ///< the point's distance from the camera centre
};

/// The term of a frame pixel with point `p_c` (camera frame; `p_w` in the world) and normal
/// `n_c` (zero: no point), paired with the model's point `q_w` and normal `m_w` (zero: no
/// surface) at the model pixel its point projects to (`inside`: there is one, see
/// icp_model_pixel). No pair where the pixel has no normal or no model pixel or surface, or
/// where the two lie farther apart than the maximum distance or their normals more than the
/// maximum angle. The weight is the robust loss's over the sensor's noise at the point's depth.
/// Branch-free, so that loops over a row vectorize: every field is computed, whatever the
/// verdict.
HIVOX_HD HIVOX_FORCEINLINE IcpTerm icp_pair_term(const IcpPass& c, const Vec3f& p_c,
                                                 const Vec3f& n_c, const Vec3f& p_w, bool inside,
                                                 const Vec3f& q_w, const Vec3f& m_w) {
  IcpTerm term;
  const Vec3f diff = p_w - q_w;
  term.paired = !is_zero(n_c) & inside & !is_zero(m_w) & !(dot(diff, diff) > c.max_distance2_m2) &
                !(dot(c.T_wc.rotate(n_c), m_w) < c.cos_max_angle);
  term.r = point_to_plane(p_w, q_w, m_w, c.T_wc.t, &term.J);
  const float s = c.noise.sigma_m(p_c.z);
  const float sigma2 = s * s + c.residual_floor2_m2;
  term.sqrt_weight =
      std::sqrt(robust_weight(term.r / std::sqrt(sigma2), c.loss, c.robust_scale) / sigma2);
  term.distance_m = norm(p_w - c.T_wc.t);
  return term;
}

}  // namespace hivox::kernels

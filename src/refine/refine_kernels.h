#pragma once
// The complexity criteria that decide where blocks split and merge, written once for CPU and
// CUDA (the edits themselves are the map's: src/map/hierarchy_kernels.h).

#include "hivox/core/hd.h"
#include "hivox/core/math.h"
#include "hivox/map/map_view.h"
#include "hivox/refine/params.h"

namespace hivox::kernels {

// ---- complexity ------------------------------------------------------------------------------

/// Voxels farther from the surface than this fraction of the truncation do not enter the detail
/// criterion. Seen at incidence theta, a voxel's projective distance is its true distance over
/// cos theta, so beyond ~cos theta of the truncation some frames clamped it at +-1: its fused
/// value bends away from linear with the mix of viewing angles, which second differences read as
/// detail (on the synthetic desk, a flat table top seen at ~60 degrees stayed split for it).
constexpr float kDetailBand = 0.75f;

/// One sample of the detail criterion (block_detail_m): voxel `i`'s squared second difference
/// along `axis` and its weight; false where voxel `i` gives none.
HIVOX_HD inline bool detail_sample(const TsdfVoxel* v, int axis, int i, int min_weight, float* d2,
                                   float* weight) {
  const int stride = axis == 0 ? 1 : (axis == 1 ? kBlockSide : kBlockSide * kBlockSide);
  const Vec3i c = voxel_coords(i);
  const int along = c[axis];
  if ((along & 1) == 0 || along == kBlockSide - 1) return false;  // odd, with both neighbours
  const TsdfVoxel a = v[i - stride], m = v[i], b = v[i + stride];
  if (a.weight < min_weight || m.weight < min_weight || b.weight < min_weight) return false;
  const float fa = tsdf_to_float(a.tsdf), fm = tsdf_to_float(m.tsdf), fb = tsdf_to_float(b.tsdf);
  if (fabsf(fm) >= kDetailBand || fabsf(fa) >= kDetailBand || fabsf(fb) >= kDetailBand)
    return false;
  const float d = fm - 0.5f * (fa + fb);
  *d2 = d * d;
  *weight = static_cast<float>(m.weight);
  return true;
}

/// The detail criterion from its sums over the block's `n` samples (see block_detail_m).
HIVOX_HD inline float detail_from_sums(float sum, float weights, int n, float mu_m, int min_samples,
                                       float* mean_weight) {
  if (mean_weight != nullptr) *mean_weight = n > 0 ? weights / static_cast<float>(n) : 0.0f;
  if (n < min_samples || n == 0) return -1.0f;
  return sqrtf(sum / static_cast<float>(n)) * mu_m;
}

/// Detail criterion: RMS, in metres, of F(v) - (F(v - e) + F(v + e)) / 2 over voxels v with an
/// odd coordinate along axis e (what subsampling to the coarser level loses), counting only
/// voxels whose three voxels are observed `min_weight` times and lie within `kDetailBand` of the
/// surface. Returns -1 when fewer than `min_samples` such samples exist (too little surface to
/// judge).
/// `mean_weight` (optional) receives the mean observation count of the sampled voxels.
HIVOX_HD inline float block_detail_m(const TsdfVoxel* v, float mu_m, int min_weight,
                                     int min_samples, float* mean_weight = nullptr) {
  float sum = 0.0f, weights = 0.0f;
  int n = 0;
  for (int axis = 0; axis < 3; ++axis) {
    for (int i = 0; i < kBlockVoxels; ++i) {
      float d2, w;
      if (!detail_sample(v, axis, i, min_weight, &d2, &w)) continue;
      sum += d2;
      weights += w;
      ++n;
    }
  }
  return detail_from_sums(sum, weights, n, mu_m, min_samples, mean_weight);
}

/// Surface this level cannot mesh: the block's inner cells (7^3, within the block) that have a
/// corner in front of the surface within the truncation band (0 < F < 1), observed `min_weight`
/// times, and an unobserved corner. Seen at a grazing angle, a coarse cell's corners behind the
/// surface lie beyond the band along the rays and are never updated, so the surface between them
/// and the observed corners is lost; a finer level's voxels lie nearer the surface and are
/// observed. (observed_in_band_front: such a front corner.)
HIVOX_HD inline bool observed_in_band_front(const TsdfVoxel& v, int min_weight) {
  return v.weight >= min_weight && v.tsdf > 0 && v.tsdf < static_cast<int16_t>(kTsdfScale);
}
/// Whether the cell with lowest corner (x, y, z) (each < 7) is unmeshable (see above).
HIVOX_HD inline bool unmeshable_cell(const TsdfVoxel* v, int x, int y, int z, int min_weight) {
  bool front = false, unobserved = false;
  for (int c = 0; c < 8; ++c) {
    const TsdfVoxel w = v[voxel_index(x + (c & 1), y + ((c >> 1) & 1), z + (c >> 2))];
    unobserved |= w.weight == 0;
    front |= observed_in_band_front(w, min_weight);
  }
  return front && unobserved;
}
HIVOX_HD inline int block_unmeshable_cells(const TsdfVoxel* v, int min_weight) {
  bool any_unobserved = false, any_front = false;  // most blocks have none of one or the other
  for (int i = 0; i < kBlockVoxels; ++i) {
    any_unobserved |= v[i].weight == 0;
    any_front |= observed_in_band_front(v[i], min_weight);
  }
  if (!any_unobserved || !any_front) return 0;
  int n = 0;
  for (int z = 0; z + 1 < kBlockSide; ++z)
    for (int y = 0; y + 1 < kBlockSide; ++y)
      for (int x = 0; x + 1 < kBlockSide; ++x) n += unmeshable_cell(v, x, y, z, min_weight);
  return n;
}

/// The paper's criterion: det(E[n n^T] - E[n] E[n]^T) of the unit forward-difference gradients
/// n over the inner 7^3 voxels whose four voxels are observed `min_weight` times; sums divided
/// by 512 as in the authors' implementation.
HIVOX_HD inline float block_det_cov(const TsdfVoxel* v, int min_weight) {
  float s1[3] = {0, 0, 0};
  float s2[6] = {0, 0, 0, 0, 0, 0};  // xx, xy, xz, yy, yz, zz
  for (int z = 0; z < kBlockSide - 1; ++z)
    for (int y = 0; y < kBlockSide - 1; ++y)
      for (int x = 0; x < kBlockSide - 1; ++x) {
        const int i = voxel_index(x, y, z);
        const TsdfVoxel c = v[i], vx = v[i + 1], vy = v[i + kBlockSide],
                        vz = v[i + kBlockSide * kBlockSide];
        if (c.weight < min_weight || vx.weight < min_weight || vy.weight < min_weight ||
            vz.weight < min_weight)
          continue;
        // Differences of the int16 values, which are exact: on a plateau the gradient is exactly
        // zero. Differences of tsdf_to_float values need not be (a compiler may fuse one of the
        // two scalings with the subtraction), and a plateau voxel would count with direction
        // (1, 1, 1).
        const Vec3f g{static_cast<float>(vx.tsdf - c.tsdf), static_cast<float>(vy.tsdf - c.tsdf),
                      static_cast<float>(vz.tsdf - c.tsdf)};
        const float len = norm(g);
        if (len <= 0.0f) continue;
        const Vec3f n = g / len;
        s1[0] += n.x;
        s1[1] += n.y;
        s1[2] += n.z;
        s2[0] += n.x * n.x;
        s2[1] += n.x * n.y;
        s2[2] += n.x * n.z;
        s2[3] += n.y * n.y;
        s2[4] += n.y * n.z;
        s2[5] += n.z * n.z;
      }
  const float k = 1.0f / static_cast<float>(kBlockVoxels);
  const float m[3] = {s1[0] * k, s1[1] * k, s1[2] * k};
  const float xx = s2[0] * k - m[0] * m[0], xy = s2[1] * k - m[0] * m[1];
  const float xz = s2[2] * k - m[0] * m[2], yy = s2[3] * k - m[1] * m[1];
  const float yz = s2[4] * k - m[1] * m[2], zz = s2[5] * k - m[2] * m[2];
  return xx * (yy * zz - yz * yz) - xy * (xy * zz - yz * xz) + xz * (xy * yz - yy * xz);
}

struct RefineLevels;
/// RefineParams' levels as kernels take them (src/refine/params.cpp).
RefineLevels refine_levels(const RefineParams& p);

/// The settings behind RefineParams::split_level and merge_level, as plain data for kernels.
struct RefineLevels {
  float split_threshold = 0, merge_threshold = 0;
  float split_noise_factor = 0, merge_noise_ratio = 0, settled_weight = 0;
  bool noise_scaled = false;  ///< the Detail criterion: levels follow the sensor's noise
};

/// The detail above which a block splits: the threshold, or the sensor's noise `sigma_m` at the
/// block times the split noise factor where that is larger, raised by sqrt(settled / observed)
/// while the block's mean weight is below the settled weight (fused noise shrinks with the
/// observations).
HIVOX_HD inline float split_level(const RefineLevels& p, float sigma_m, float mean_weight) {
  if (!p.noise_scaled) return p.split_threshold;
  const float young = mean_weight >= p.settled_weight || mean_weight <= 0.0f
                          ? 1.0f
                          : sqrtf(p.settled_weight / mean_weight);
  const float n = p.split_noise_factor * sigma_m * young;
  return n > p.split_threshold ? n : p.split_threshold;
}

/// The detail below which eight siblings merge (see split_level).
HIVOX_HD inline float merge_level(const RefineLevels& p, float sigma_m) {
  if (!p.noise_scaled) return p.merge_threshold;
  const float n = p.merge_noise_ratio * p.split_noise_factor * sigma_m;
  return n > p.merge_threshold ? n : p.merge_threshold;
}

}  // namespace hivox::kernels

#pragma once
// Complexity criteria and the data side of split and merge, written once for CPU and CUDA.

#include "hivox/core/atomic.h"
#include "hivox/core/hd.h"
#include "hivox/core/math.h"
#include "hivox/map/map_view.h"

namespace hivox::kernels {

// ---- complexity ------------------------------------------------------------------------------

/// Voxels farther from the surface than this fraction of the truncation do not enter the detail
/// criterion. Seen at incidence theta, a voxel's projective distance is its true distance over
/// cos theta, so beyond ~cos theta of the truncation some frames clamped it at +-1: its fused
/// value bends away from linear with the mix of viewing angles, which second differences read as
/// detail (on the synthetic desk, a flat table top seen at ~60 degrees stayed split for it).
constexpr float kDetailBand = 0.75f;

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
    const int stride = axis == 0 ? 1 : (axis == 1 ? kBlockSide : kBlockSide * kBlockSide);
    for (int i = 0; i < kBlockVoxels; ++i) {
      const Vec3i c = voxel_coords(i);
      const int along = c[axis];
      if ((along & 1) == 0 || along == kBlockSide - 1) continue;  // odd, with both neighbours
      const TsdfVoxel a = v[i - stride], m = v[i], b = v[i + stride];
      if (a.weight < min_weight || m.weight < min_weight || b.weight < min_weight) continue;
      const float fa = tsdf_to_float(a.tsdf), fm = tsdf_to_float(m.tsdf),
                  fb = tsdf_to_float(b.tsdf);
      if (fabsf(fm) >= kDetailBand || fabsf(fa) >= kDetailBand || fabsf(fb) >= kDetailBand)
        continue;
      const float d = fm - 0.5f * (fa + fb);
      sum += d * d;
      weights += static_cast<float>(m.weight);
      ++n;
    }
  }
  if (mean_weight != nullptr) *mean_weight = n > 0 ? weights / static_cast<float>(n) : 0.0f;
  if (n < min_samples || n == 0) return -1.0f;
  return sqrtf(sum / static_cast<float>(n)) * mu_m;
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

// ---- split: children from the parent ---------------------------------------------------------

/// Fills child `child` (offset (child & 1, (child >> 1) & 1, child >> 2)) of a splitting parent
/// by trilinear interpolation of the parent's voxels. `parent_blocks[d]` holds the parent's block
/// (d = 0) and its +x/+y/+z neighbours at the parent's level (d = dx | dy << 1 | dz << 2;
/// kPtrEmpty when absent): the last half voxel of the parent interpolates towards the neighbour,
/// or takes the parent's border voxel when there is none. Unobserved voxels do not enter the
/// average (their default value is not a measurement). Weights are interpolated and scaled by
/// `weight_scale`. Returns the child's surface summary.
HIVOX_HD inline BlockSurface fill_split_child(const MapView& map, const int32_t parent_blocks[8],
                                              int child, int32_t child_ptr, float weight_scale) {
  const int ox = child & 1, oy = (child >> 1) & 1, oz = child >> 2;
  TsdfVoxel* out = map.tsdf + static_cast<int64_t>(child_ptr) * kBlockVoxels;
  ColorVoxel* out_c =
      map.color ? map.color + static_cast<int64_t>(child_ptr) * kBlockVoxels : nullptr;
  for (int i = 0; i < kBlockVoxels; ++i) {
    const Vec3i j = voxel_coords(i);
    // Parent coordinate of the child voxel: (8 o + j) / 2, i.e. a parent voxel or a midpoint.
    const int qx = 4 * ox + (j.x >> 1), qy = 4 * oy + (j.y >> 1), qz = 4 * oz + (j.z >> 1);
    const int hx = j.x & 1, hy = j.y & 1, hz = j.z & 1;  // 1: halfway to the next parent voxel
    float f_sum = 0.0f, f_w = 0.0f, w_sum = 0.0f;
    float r = 0.0f, g = 0.0f, b = 0.0f, c_w = 0.0f, cw_sum = 0.0f;
    for (int c = 0; c < 8; ++c) {
      const int cx = c & 1, cy = (c >> 1) & 1, cz = c >> 2;
      if ((cx > hx) | (cy > hy) | (cz > hz)) continue;  // corner not involved
      const float a = (hx ? 0.5f : 1.0f) * (hy ? 0.5f : 1.0f) * (hz ? 0.5f : 1.0f);
      int px = qx + cx, py = qy + cy, pz = qz + cz;
      const int d = (px >> 3) | ((py >> 3) << 1) | ((pz >> 3) << 2);
      int32_t ptr = parent_blocks[d];
      if (ptr < 0) {  // no neighbour at this level: take the parent's border voxel
        ptr = parent_blocks[0];
        px = px > 7 ? 7 : px;
        py = py > 7 ? 7 : py;
        pz = pz > 7 ? 7 : pz;
      }
      const int vi = voxel_index(px & 7, py & 7, pz & 7);
      const TsdfVoxel vox = map.tsdf[static_cast<int64_t>(ptr) * kBlockVoxels + vi];
      w_sum += a * static_cast<float>(vox.weight);
      if (vox.weight > 0) {
        f_sum += a * tsdf_to_float(vox.tsdf);
        f_w += a;
      }
      if (out_c != nullptr) {
        const ColorVoxel col = map.color[static_cast<int64_t>(ptr) * kBlockVoxels + vi];
        cw_sum += a * static_cast<float>(col.weight);
        if (col.weight > 0) {
          r += a * col.r;
          g += a * col.g;
          b += a * col.b;
          c_w += a;
        }
      }
    }
    TsdfVoxel v;
    if (f_w > 0.0f) {
      v.tsdf = tsdf_from_float(f_sum / f_w);
      const float w = w_sum * weight_scale + 0.5f;
      v.weight = static_cast<uint16_t>(w < 1.0f ? 1.0f : w);
    }
    out[i] = v;
    if (out_c != nullptr) {
      ColorVoxel cv;
      if (c_w > 0.0f) {
        const float inv = 1.0f / c_w;
        cv.r = static_cast<uint8_t>(r * inv + 0.5f);
        cv.g = static_cast<uint8_t>(g * inv + 0.5f);
        cv.b = static_cast<uint8_t>(b * inv + 0.5f);
        const float w = cw_sum * weight_scale + 0.5f;
        cv.weight = static_cast<uint8_t>(w < 1.0f ? 1.0f : (w > 255.0f ? 255.0f : w));
      }
      out_c[i] = cv;
    }
  }
  return block_surface(out);
}

// ---- merge: the parent from its children -----------------------------------------------------

/// Fills a merged parent block by subsampling its 8 children (`child_ptrs[c]`, c = cx | cy << 1 |
/// cz << 2): parent voxel i takes child voxel 2 (i mod 4) of child i / 4 along each axis, the
/// sample at the same position. A split followed by a merge gives back the parent exactly.
/// Returns the parent's surface summary.
HIVOX_HD inline BlockSurface fill_merged_parent(const MapView& map, const int32_t child_ptrs[8],
                                                int32_t parent_ptr) {
  TsdfVoxel* out = map.tsdf + static_cast<int64_t>(parent_ptr) * kBlockVoxels;
  ColorVoxel* out_c =
      map.color ? map.color + static_cast<int64_t>(parent_ptr) * kBlockVoxels : nullptr;
  for (int i = 0; i < kBlockVoxels; ++i) {
    const Vec3i p = voxel_coords(i);
    const int child = (p.x >> 2) | ((p.y >> 2) << 1) | ((p.z >> 2) << 2);
    const int src = voxel_index(2 * (p.x & 3), 2 * (p.y & 3), 2 * (p.z & 3));
    const int64_t at = static_cast<int64_t>(child_ptrs[child]) * kBlockVoxels + src;
    out[i] = map.tsdf[at];
    if (out_c != nullptr) out_c[i] = map.color[at];
  }
  return block_surface(out);
}

/// Removes entry `e` (already Empty) from its chain when it is the chain's tail and lies in the
/// excess area, so that chains shrink only at their end; returns true when unlinked (the caller
/// returns it to the level's excess free list). Safe against other threads doing the same.
HIVOX_HD inline bool unlink_tail_entry(const LevelView& lv, int32_t e, const Vec3i& pos) {
  if (e <= static_cast<int32_t>(lv.bucket_mask) || atomic_load(&lv.entries[e].next) != kNoEntry)
    return false;
  int32_t i = static_cast<int32_t>(block_hash(pos, lv.bucket_mask));
  while (i != kNoEntry) {
    const int32_t next = atomic_load(&lv.entries[i].next);
    if (next == e) return atomic_cas(&lv.entries[i].next, e, kNoEntry) == e;
    i = next;
  }
  return false;
}

}  // namespace hivox::kernels

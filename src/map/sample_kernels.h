#pragma once
// Reading the TSDF at any point, across levels, written once for every driver (raycast,
// meshing, evaluation; CPU and CUDA).

#include <cfloat>
#include <climits>

#include "hivox/core/hd.h"
#include "hivox/core/math.h"
#include "hivox/map/map_view.h"

namespace hivox::kernels {

/// A slot of a direct-mapped cache of block look-ups: block `pos` of `level` and its `ptr`
/// (level -1: empty).
struct BlockSlot {
  Vec3i pos;
  int32_t level = -1;
  int32_t ptr = kPtrEmpty;
  HIVOX_HD bool holds(int lvl, const Vec3i& p) const { return level == lvl && pos == p; }
};

/// The slot of block `p` of level `lvl` among `slots` (a power of two) direct-mapped slots.
HIVOX_HD inline uint32_t block_slot(int lvl, const Vec3i& p, uint32_t slots) {
  return (block_hash(p, slots - 1) + static_cast<uint32_t>(lvl) * 17u) & (slots - 1);
}

/// Direct-mapped cache of block look-ups (absent blocks included). Neighbouring samples (along a
/// ray, between neighbouring rays, across a mesh block) mostly need the same few blocks; a CPU
/// driver keeps one cache per thread, a GPU thread one of its own. Valid while the map's layout
/// does not change. A cache is a local of one thread and never crosses between host and device,
/// so its size may differ between the two.
struct BlockLookupCache {
#if defined(__CUDA_ARCH__)
  static constexpr int kSlots = 16;  // 320 B of a GPU thread's local memory: one ray's blocks
#else
  static constexpr int kSlots = 4096;  // 80 KB: a CPU thread's row of rays crosses ~100 blocks
#endif
  BlockSlot slots[kSlots];
#if !defined(__CUDA_ARCH__)
  /// Look-ups the cache did not answer (each a search of the hash table): what a cost model of
  /// the device's rays counts (bench/ray_cost). Host only.
  int64_t table_lookups = 0;
  /// Cells sampled across levels (some corner stored at another level), and of them those
  /// interpolated on their irregular corners. Host only, as table_lookups.
  int64_t cross_level_cells = 0, irregular_cells = 0;
#endif

  HIVOX_HD void reset() {
    for (int i = 0; i < kSlots; ++i) slots[i].level = -1;
  }
  /// `ptr` of block `p` at `lvl` (kPtrEmpty when absent), from the cache or the hash table.
  HIVOX_HD int32_t find(const MapView& map, int lvl, const Vec3i& p) {
    BlockSlot& s = slots[block_slot(lvl, p, kSlots)];
    if (s.holds(lvl, p)) return s.ptr;
    s = {p, lvl, find_block_ptr(map.level[lvl], p)};
#if !defined(__CUDA_ARCH__)
    ++table_lookups;
#endif
    return s.ptr;
  }
};

/// The block storing world point `p_w`. Returns the block's ptr, or kPtrEmpty when nothing is
/// stored there; `level` and `pos` receive the level and block where the search ended: the
/// stored block, else the coarsest level with nothing there.
/// The search starts at `start_level` (the coarsest level when it is out of range): from a
/// level that stores the point it takes one look-up instead of one per level above it (a
/// surface's neighbouring samples mostly lie at one level). From there it descends through Split
/// entries, or climbs while nothing is stored, until a stored block, or a Split entry above
/// an empty one. Since every stored block's coarser ancestors are Split and no region is stored
/// at two levels, it ends where the descent from the coarsest level ends, from any start.
HIVOX_HD inline int32_t locate_block(const MapView& map, BlockLookupCache& cache, const Vec3f& p_w,
                                     int* level, Vec3i* pos, int start_level = -1) {
  int l = start_level >= 0 && start_level < map.levels ? start_level : map.levels - 1;
  Vec3i b = block_of_point(map.level[l], p_w);
  int32_t ptr = cache.find(map, l, b);
  if (ptr == kPtrSplit) {
    while (ptr == kPtrSplit && l > 0) {
      --l;
      b = block_of_point(map.level[l], p_w);
      ptr = cache.find(map, l, b);
    }
  } else {
    while (ptr < 0 && l + 1 < map.levels) {
      const Vec3i up = block_of_point(map.level[l + 1], p_w);
      const int32_t up_ptr = cache.find(map, l + 1, up);
      // A Split entry has all 8 children, so this is a guard: the region is level l's, and empty.
      if (up_ptr == kPtrSplit) break;
      l = l + 1;
      b = up;
      ptr = up_ptr;
    }
  }
  *level = l;
  *pos = b;
  return ptr == kPtrSplit ? kPtrEmpty : ptr;
}

/// The function of the trilinear form through 8 samples at arbitrary positions (paper §V):
/// F(Q) = a[0] XYZ + a[1] XY + a[2] YZ + a[3] XZ + a[4] X + a[5] Y + a[6] Z + a[7], with
/// (X, Y, Z) = Q the offset from sample 0's position (voxel units of the cell's level).
struct IrregularInterpolant {
  Vec3f origin;  ///< sample 0's position
  float a[8];
  /// F at offset `q` from `origin`, with its gradient.
  HIVOX_HD float at(const Vec3f& q, Vec3f* gradient) const {
    gradient->x = a[0] * q.y * q.z + a[1] * q.y + a[3] * q.z + a[4];
    gradient->y = a[0] * q.x * q.z + a[1] * q.x + a[2] * q.z + a[5];
    gradient->z = a[0] * q.x * q.y + a[2] * q.y + a[3] * q.x + a[6];
    return a[0] * q.x * q.y * q.z + a[1] * q.x * q.y + a[2] * q.y * q.z + a[3] * q.x * q.z +
           a[4] * q.x + a[5] * q.y + a[6] * q.z + a[7];
  }
  /// F along the ray through offset `q` with direction `d`: F(q + s d) = p[0] + s (p[1] +
  /// s (p[2] + s p[3])).
  HIVOX_HD void along_ray(const Vec3f& q, const Vec3f& d, float p[4]) const {
    Vec3f g;
    p[0] = at(q, &g);
    p[1] = g.x * d.x + g.y * d.y + g.z * d.z;
    p[2] = a[0] * (q.x * d.y * d.z + q.y * d.x * d.z + q.z * d.x * d.y) + a[1] * d.x * d.y +
           a[2] * d.y * d.z + a[3] * d.x * d.z;
    p[3] = a[0] * d.x * d.y * d.z;
  }
};

/// Irregular-grid interpolation (paper §V): the function of the trilinear form through 8 samples
/// `value` at positions `pos` (IrregularInterpolant). Sample 0 is moved to the origin, which gives
/// a[7] = F0 and leaves a 7x7 system, solved by Gaussian elimination with partial pivoting.
/// Returns false (and leaves `out` untouched) when the positions are degenerate (a pivot below
/// 1e-6): the caller falls back.
HIVOX_HD HIVOX_DEVICE_NOINLINE inline bool solve_irregular(const Vec3f pos[8], const float value[8],
                                                           IrregularInterpolant* out) {
  float a[7][8];  // augmented rows: 7 coefficients (a1..a7) and the right-hand side
  for (int i = 0; i < 7; ++i) {
    const Vec3f q = pos[i + 1] - pos[0];
    a[i][0] = q.x * q.y * q.z;
    a[i][1] = q.x * q.y;
    a[i][2] = q.y * q.z;
    a[i][3] = q.x * q.z;
    a[i][4] = q.x;
    a[i][5] = q.y;
    a[i][6] = q.z;
    a[i][7] = value[i + 1] - value[0];
  }
  for (int c = 0; c < 7; ++c) {
    int pivot = c;
    for (int r = c + 1; r < 7; ++r)
      if (fabsf(a[r][c]) > fabsf(a[pivot][c])) pivot = r;
    if (fabsf(a[pivot][c]) < 1e-6f) return false;
    if (pivot != c)
      for (int k = 0; k < 8; ++k) {
        const float t = a[c][k];
        a[c][k] = a[pivot][k];
        a[pivot][k] = t;
      }
    for (int r = c + 1; r < 7; ++r) {
      const float m = a[r][c] / a[c][c];
      for (int k = c; k < 8; ++k) a[r][k] -= m * a[c][k];
    }
  }
  for (int r = 6; r >= 0; --r) {
    float s = a[r][7];
    for (int k = r + 1; k < 7; ++k) s -= a[r][k] * out->a[k];
    out->a[r] = s / a[r][r];
  }
  out->a[7] = value[0];
  out->origin = pos[0];
  return true;
}

/// The irregular interpolant through samples `value` at `pos` (solve_irregular) evaluated at `p`,
/// with its gradient; false when the positions are degenerate.
HIVOX_HD inline bool interpolate_irregular(const Vec3f pos[8], const float value[8], const Vec3f& p,
                                           float* f, Vec3f* gradient) {
  IrregularInterpolant in;
  if (!solve_irregular(pos, value, &in)) return false;
  *f = in.at(p - in.origin, gradient);
  return true;
}

/// Trilinear interpolation of 8 corner values (corner c = (c & 1, (c >> 1) & 1, c >> 2)) at
/// fractional position t, with the gradient per voxel.
HIVOX_HD inline float interpolate_trilinear(const float v[8], const Vec3f& t, Vec3f* gradient) {
  const float x0 = v[0] + (v[1] - v[0]) * t.x, x1 = v[2] + (v[3] - v[2]) * t.x;
  const float x2 = v[4] + (v[5] - v[4]) * t.x, x3 = v[6] + (v[7] - v[6]) * t.x;
  const float y0 = x0 + (x1 - x0) * t.y, y1 = x2 + (x3 - x2) * t.y;
  const float dx0 = v[1] - v[0], dx1 = v[3] - v[2], dx2 = v[5] - v[4], dx3 = v[7] - v[6];
  const float dxy0 = dx0 + (dx1 - dx0) * t.y, dxy1 = dx2 + (dx3 - dx2) * t.y;
  gradient->x = dxy0 + (dxy1 - dxy0) * t.z;
  gradient->y = (x1 - x0) + ((x3 - x2) - (x1 - x0)) * t.z;
  gradient->z = y1 - y0;
  return y0 + (y1 - y0) * t.z;
}

/// The root of F(s) = p0 + s (p1 + s (p2 + s p3)), a function of the trilinear form along a ray
/// (crossing_in_cell), on the side of s = 0 the sign of p0 calls for (ahead of a positive value,
/// behind a non-positive one) as far as the ray stays in the cell: the ray passes fractional
/// position `t` of the cell with direction `dv` (`inv_dv` its reciprocal per axis, see
/// crossing_in_cell). False position with the Illinois rule (7 steps, then a secant). Returns
/// false when that part of the ray has no sign change; otherwise the root's offset in ray
/// parameter goes to `dz` and its fractional position to `t_hit`. Without branches.
HIVOX_HD HIVOX_FORCEINLINE bool crossing_on_ray(float p0, float p1, float p2, float p3,
                                                const Vec3f& t, const Vec3f& dv,
                                                const Vec3f& inv_dv, float* dz, Vec3f* t_hit) {
  auto value_at = [&](float s) { return p0 + s * (p1 + s * (p2 + s * p3)); };
  // The ray's segment inside the cell, [s_in, s_out] around t (s_in <= 0 <= s_out).
  float s_in = -FLT_MAX, s_out = FLT_MAX;
  HIVOX_UNROLL(3)
  for (int k = 0; k < 3; ++k) {
    const float a = -t[k] * inv_dv[k], b = (1.0f - t[k]) * inv_dv[k];
    const float lo = a < b ? a : b, hi = a < b ? b : a;
    s_in = lo > s_in ? lo : s_in;
    s_out = hi < s_out ? hi : s_out;
  }
  const bool ahead = p0 > 0.0f;
  const float s_end = ahead ? s_out : s_in;
  const float f_end = value_at(s_end);
  // The bracket: a on the positive side, b on the other.
  float a = ahead ? 0.0f : s_end, fa = ahead ? p0 : f_end;
  float b = ahead ? s_end : 0.0f, fb = ahead ? f_end : p0;
  const bool found = fa > 0.0f && fb <= 0.0f;
  // The secant through the bracket's ends (fa > 0 >= fb keeps the denominator positive; the
  // division is unconditional, its operand guarded: a vectorized loop cannot branch).
  auto secant = [&] { return a + (b - a) * (fa / (found ? fa - fb : 1.0f)); };
  int kept = 0;  // which end the last two steps kept (1: a, -1: b), for the Illinois rule
  HIVOX_UNROLL(7)
  for (int i = 0; i < 7; ++i) {
    const float m = secant();
    const float fm = value_at(m);
    const bool positive = fm > 0.0f;
    // Replacing the same end twice in a row halves the other end's value (Illinois).
    fb = positive && kept == -1 ? 0.5f * fb : fb;
    fa = !positive && kept == 1 ? 0.5f * fa : fa;
    kept = positive ? -1 : 1;
    a = positive ? m : a;
    fa = positive ? fm : fa;
    b = positive ? b : m;
    fb = positive ? fb : fm;
  }
  const float s = secant();
  *dz = s;
  *t_hit = Vec3f{clampf(t.x + dv.x * s, 0.0f, 1.0f), clampf(t.y + dv.y * s, 0.0f, 1.0f),
                 clampf(t.z + dv.z * s, 0.0f, 1.0f)};
  return found;
}

/// Where a ray crosses the surface from its front (the interpolant going from positive to
/// non-positive) inside one trilinear cell of values `v`. The ray passes fractional position `t`
/// with direction `dv` (cell units per unit of ray parameter; `inv_dv` its reciprocal per axis,
/// any value of the right sign beyond 1e20 where a component is 0). Along a ray the interpolant is
/// a cubic in the ray parameter, whose root crossing_on_ray finds: exact for the linear TSDF of a
/// plane and within ~0.005 voxel even for cubics far more curved than a TSDF's. Without branches,
/// so that the cells of a ray packet solve in one vectorized loop.
HIVOX_HD HIVOX_FORCEINLINE bool crossing_in_cell(const float v[8], const Vec3f& t, const Vec3f& dv,
                                                 const Vec3f& inv_dv, float* dz, Vec3f* t_hit) {
  // The interpolant as a polynomial in the cell's coordinates, then along the ray:
  // F(t + s dv) = p0 + s (p1 + s (p2 + s p3)).
  const float cx = v[1] - v[0], cy = v[2] - v[0], cz = v[4] - v[0];
  const float cxy = v[3] - v[2] - cx, cxz = v[5] - v[4] - cx, cyz = v[6] - v[4] - cy;
  const float cxyz = v[7] - v[6] - v[5] + v[4] - v[3] + v[2] + cx;
  const float fxy = cxy + cxyz * t.z, fxz = cxz + cxyz * t.y, fyz = cyz + cxyz * t.x;
  const float fx = cx + cxy * t.y + cxz * t.z + cxyz * t.y * t.z;
  const float fy = cy + cxy * t.x + cyz * t.z + cxyz * t.x * t.z;
  const float fz = cz + cxz * t.x + cyz * t.y + cxyz * t.x * t.y;
  const float p0 = v[0] + cx * t.x + cy * t.y + cz * t.z + cxy * t.x * t.y + cxz * t.x * t.z +
                   cyz * t.y * t.z + cxyz * t.x * t.y * t.z;
  const float p1 = fx * dv.x + fy * dv.y + fz * dv.z;
  const float p2 = fxy * dv.x * dv.y + fxz * dv.x * dv.z + fyz * dv.y * dv.z;
  const float p3 = cxyz * dv.x * dv.y * dv.z;
  return crossing_on_ray(p0, p1, p2, p3, t, dv, inv_dv, dz, t_hit);
}

/// Per axis 1 / d, and a value of the right sign beyond 1e20 where d is 0 (crossing_in_cell's
/// `inv_dv`).
HIVOX_HD inline Vec3f inverse_direction(const Vec3f& d) {
  Vec3f inv;
  for (int k = 0; k < 3; ++k) inv[k] = 1.0f / (fabsf(d[k]) > 1e-20f ? d[k] : 1e-30f);
  return inv;
}

/// The interpolation cell of a level around a point: `q` the point in voxel units, `base` the
/// cell's lowest voxel (global voxel coordinates), `local` that voxel's place in its block,
/// `block` that block, `t` the point's fractional position in the cell.
struct CellCoords {
  Vec3f q;
  Vec3i base, local, block;
  Vec3f t;
  /// Whether the cell's 8 voxels reach beyond the block of its lowest voxel.
  HIVOX_HD bool spans_blocks() const { return (local.x == 7) | (local.y == 7) | (local.z == 7); }
  /// Per axis, 1 where the cell reaches into the next block (neighbour_blocks' span).
  HIVOX_HD Vec3i span() const { return {local.x == 7, local.y == 7, local.z == 7}; }
};

HIVOX_HD inline CellCoords cell_at(const LevelView& lv, const Vec3f& p_w) {
  CellCoords c;
  c.q = p_w * lv.inv_voxel_size;
  c.base = floor_to_int(c.q);
  c.local = {c.base.x & 7, c.base.y & 7, c.base.z & 7};
  c.block = block_of_voxel(c.base);
  c.t = c.q - to_float(c.base);
  return c;
}

/// The corner of a cell nearest to fractional position t (corner c as in read_cell).
HIVOX_HD inline int nearest_corner(const Vec3f& t) {
  return (t.x >= 0.5f ? 1 : 0) | (t.y >= 0.5f ? 2 : 0) | (t.z >= 0.5f ? 4 : 0);
}

/// TsdfSample::crossing_dz of a sample without a crossing.
constexpr float kNoCrossing = FLT_MAX;

/// A TSDF sample: value, gradient (per voxel of its level) and the voxel nearest to the point.
struct TsdfSample {
  float f = 1.0f;
  Vec3f gradient;  ///< dF / d(voxel) of the interpolant at the point
  int32_t nearest_ptr = kPtrEmpty;
  int nearest_index = 0;  ///< voxel index inside `nearest_ptr`
  /// Samplers given a ray also look for its crossing inside the sample's trilinear cell
  /// (crossing_in_cell): where they find one, this is its offset in ray parameter from the
  /// sampled point, and the sample describes the crossing (value ~0, its gradient and nearest
  /// voxel) instead of the point; otherwise kNoCrossing.
  float crossing_dz = kNoCrossing;
  HIVOX_HD bool at_crossing() const { return crossing_dz != kNoCrossing; }
};

/// Fills `out` from cell values `v` at fractional position `t`; given a ray (`dv`, its direction
/// in cell units per unit of ray parameter) that crosses the surface inside the cell, at that
/// crossing instead (see TsdfSample::crossing_dz). Returns the corner nearest to the point
/// described (corner c as in read_cell).
HIVOX_HD inline int sample_cell(const float v[8], const Vec3f& t, const Vec3f* dv,
                                TsdfSample* out) {
  Vec3f at = t;
  out->crossing_dz = kNoCrossing;
  float dz;
  Vec3f t_hit;
  if (dv != nullptr && crossing_in_cell(v, t, *dv, inverse_direction(*dv), &dz, &t_hit)) {
    at = t_hit;
    out->crossing_dz = dz;
  }
  out->f = interpolate_trilinear(v, at, &out->gradient);
  return nearest_corner(at);
}

/// The block of a coarser level holding the region of block `pos` of `level` (when `level`
/// itself has no block there): its ptr, its level in `holder_level`; kPtrEmpty when no coarser
/// level stores the region. `find(l, p)` gives the ptr of block `p` of level `l` (a cache's, or
/// find_block_ptr where a caller has no cache).
template <typename Find>
HIVOX_HD inline int32_t find_coarser_holder(const MapView& map, int level, const Vec3i& pos,
                                            int* holder_level, const Find& find) {
  for (int l = level + 1; l < map.levels; ++l) {
    const int k = 1 << (l - level);
    const int32_t p = find(l, Vec3i{floor_div(pos.x, k), floor_div(pos.y, k), floor_div(pos.z, k)});
    if (p >= 0) {
      *holder_level = l;
      return p;
    }
    if (p == kPtrSplit) break;  // the finer level has nothing there
  }
  return kPtrEmpty;
}
/// find_coarser_holder through `cache`.
HIVOX_HD inline int32_t coarser_holder(const MapView& map, BlockLookupCache& cache, int level,
                                       const Vec3i& pos, int* holder_level) {
  return find_coarser_holder(map, level, pos, holder_level,
                             [&](int l, const Vec3i& p) { return cache.find(map, l, p); });
}

/// The voxel exactly at lattice point `g` of `level`: of `level` itself, or of the finer level
/// its Split entries lead to. Returns that level (the voxel's block and global coordinates there
/// go to `ptr` and `voxel`), or -1 when `level` has no block there (a coarser level may).
HIVOX_HD inline int voxel_at_or_finer(const MapView& map, BlockLookupCache& cache, int level,
                                      const Vec3i& g, int32_t* ptr, Vec3i* voxel) {
  for (int l = level; l >= 0; --l) {
    const int k = 1 << (level - l);
    const Vec3i gl{g.x * k, g.y * k, g.z * k};
    const int32_t p = cache.find(map, l, block_of_voxel(gl));
    if (p >= 0) {
      *ptr = p;
      *voxel = gl;
      return l;
    }
    if (p != kPtrSplit) break;
  }
  return -1;
}

/// The voxel standing for lattice point `g` of `level`, found with integer arithmetic only (so
/// points on block borders never land in the wrong block): the voxel of `level` itself, or of a
/// finer level, which has a voxel exactly there; where the point lies in a coarser region, that
/// level's voxel nearest to it (or, when that voxel's block lies elsewhere, the one at the
/// point's floor in the block holding the point). With `corner` (0..7, as in read_cell) the
/// coarser voxel is not the nearest but the one at or beyond the point on the corner's side of
/// its cell along each axis (floor for a low corner, ceiling for a high one), so that the two
/// corners of a cell never land on one coarse voxel; where that point's coarse block is split,
/// the finer voxel exactly at the point. Returns the level of the voxel, whose
/// block and global coordinates (at that level) go to `ptr` and `voxel`, or -1 when no level
/// stores the point.
HIVOX_HD inline int lattice_voxel(const MapView& map, BlockLookupCache& cache, int level,
                                  const Vec3i& g, int32_t* ptr, Vec3i* voxel, int corner = -1) {
  const int here = voxel_at_or_finer(map, cache, level, g, ptr, voxel);
  if (here >= 0) return here;
  int l;
  const int32_t holder = coarser_holder(map, cache, level, block_of_voxel(g), &l);
  if (holder < 0) return -1;
  const int k = 1 << (l - level);
  auto shift = [&](int axis) { return corner < 0 ? k / 2 : ((corner >> axis) & 1) * (k - 1); };
  const Vec3i pick{floor_div(g.x + shift(0), k), floor_div(g.y + shift(1), k),
                   floor_div(g.z + shift(2), k)};
  const int32_t p = cache.find(map, l, block_of_voxel(pick));
  if (p == kPtrSplit && corner >= 0) {
    // The coarse point on the corner's side lies in a finer region, which has a voxel exactly
    // there (taking the floor instead would put two corners of the cell on one sample).
    const int finer =
        voxel_at_or_finer(map, cache, level, Vec3i{pick.x * k, pick.y * k, pick.z * k}, ptr, voxel);
    if (finer >= 0) return finer;
  }
  *ptr = p >= 0 ? p : holder;
  *voxel = p >= 0 ? pick : Vec3i{floor_div(g.x, k), floor_div(g.y, k), floor_div(g.z, k)};
  return l;
}

/// The sample standing in for corner `corner` (as in read_cell) of a cell, voxel `g` (integer
/// coordinates of `level`), when its block is not stored at `level`: lattice_voxel's voxel of
/// another level, on the corner's side; `pos` receives its position in voxel units of `level`
/// (`g` itself for a finer level, but for the split-block case of lattice_voxel).
HIVOX_HD HIVOX_DEVICE_NOINLINE inline bool corner_from_other_level(const MapView& map,
                                                                   BlockLookupCache& cache,
                                                                   int level, const Vec3i& g,
                                                                   int corner, int32_t* ptr,
                                                                   int* index, Vec3f* pos) {
  Vec3i voxel;
  const int l2 = lattice_voxel(map, cache, level, g, ptr, &voxel, corner);
  if (l2 < 0 || (l2 == level && voxel == g)) return false;
  *index = local_voxel_index(voxel);
  *pos = l2 >= level ? to_float(voxel) * static_cast<float>(1 << (l2 - level))
                     : to_float(voxel) * (1.0f / static_cast<float>(1 << (level - l2)));
  return true;
}

/// Slot `d` (0..7) of the 2x2x2 blocks from `block` up: the block, `block` + (d & 1,
/// (d >> 1) & 1, d >> 2).
HIVOX_HD inline Vec3i neighbour_block(const Vec3i& block, int d) {
  return {block.x + (d & 1), block.y + ((d >> 1) & 1), block.z + (d >> 2)};
}
/// Whether slot `d` lies within `span` (0 or 1 per axis: how far past the block a cell reaches).
HIVOX_HD inline bool slot_in_span(int d, const Vec3i& span) {
  return ((d & 1) <= span.x) & (((d >> 1) & 1) <= span.y) & ((d >> 2) <= span.z);
}

/// The blocks of `level` that voxels `block`'s origin + [0, 8 + 8 * span) reach into, one or
/// two per axis (`span` 0 or 1 per axis): `ptrs[neighbour_slot(x, y, z)]` holds the block of
/// the voxel at (x, y, z) from that origin; slots beyond the span are kPtrEmpty.
HIVOX_HD HIVOX_DEVICE_NOINLINE inline void neighbour_blocks(const MapView& map,
                                                            BlockLookupCache& cache, int level,
                                                            const Vec3i& block, const Vec3i& span,
                                                            int32_t ptrs[8]) {
  for (int d = 0; d < 8; ++d)
    ptrs[d] = slot_in_span(d, span) ? cache.find(map, level, neighbour_block(block, d)) : kPtrEmpty;
}
HIVOX_HD inline int neighbour_slot(int x, int y, int z) {
  return (x >> 3) | ((y >> 3) << 1) | ((z >> 3) << 2);
}

/// The 2x2x2 blocks of a level from a block up (neighbour_blocks with span 1 on every axis),
/// looked up again only when asked for another block: consecutive cells that reach beyond one
/// block (along a ray, across a packet) mostly reach from the same block. With a `span` (0 or 1
/// per axis, as neighbour_blocks takes it), only the blocks in it are looked up, the others when
/// a later call's span reaches them: a cell that reaches beyond its block along one axis needs 2
/// of the 8, and on a GPU each look-up the cache does not answer is a chain of dependent reads.
/// Slots outside every span asked for so far hold kNotLookedUp (negative, like an absent block):
/// a caller reads only the slots of the span it asked for.
struct NeighbourBlocks {
  static constexpr int32_t kNotLookedUp = INT32_MIN;
  int level = -1;  ///< of `block` (-1: none yet)
  Vec3i block;
  int32_t ptrs[8];
  HIVOX_HD const int32_t* get(const MapView& map, BlockLookupCache& cache, int l, const Vec3i& b,
                              const Vec3i& span = {1, 1, 1}) {
    if (l != level || !(b == block)) {
      for (int d = 0; d < 8; ++d) ptrs[d] = kNotLookedUp;
      level = l;
      block = b;
    }
    for (int d = 0; d < 8; ++d)
      if (ptrs[d] == kNotLookedUp && slot_in_span(d, span))
        ptrs[d] = cache.find(map, l, neighbour_block(b, d));
    return ptrs;
  }
};

/// Corner `c` of the cell whose lowest voxel is `origin` (coordinates from the origin of
/// `blocks`' first block, see neighbour_blocks): its block's ptr (negative when not stored at
/// this level) goes to `ptr`; returns its voxel index in that block.
HIVOX_HD inline int cell_corner(const int32_t blocks[8], const Vec3i& origin, int c, int32_t* ptr) {
  const int x = origin.x + (c & 1), y = origin.y + ((c >> 1) & 1), z = origin.z + (c >> 2);
  *ptr = blocks[neighbour_slot(x, y, z)];
  return voxel_index(x & 7, y & 7, z & 7);
}

/// Reads the 8 voxels of the cell whose lowest voxel is `origin` (coordinates from the origin of
/// `blocks`' first block, see neighbour_blocks) into `v` (corner c = (c & 1, (c >> 1) & 1,
/// c >> 2)) and their smallest weight into `min_w`. Returns false when a corner's block is not
/// stored at this level.
HIVOX_HD inline bool read_cell(const MapView& map, const int32_t blocks[8], const Vec3i& origin,
                               float v[8], int* min_w) {
  int w = 65535;
  for (int c = 0; c < 8; ++c) {
    int32_t ptr;
    const int i = cell_corner(blocks, origin, c, &ptr);
    if (ptr < 0) return false;
    const TsdfVoxel vox = map.tsdf[static_cast<int64_t>(ptr) * kBlockVoxels + i];
    w = vox.weight < w ? vox.weight : w;
    v[c] = tsdf_to_float(vox.tsdf);
  }
  *min_w = w;
  return true;
}

enum class CellRead { Sampled, Unobserved, Absent };

/// The trilinear sample of `cell` from `blocks` (the blocks around its block, see
/// neighbour_blocks) when all 8 voxels are stored there: Sampled (`out` filled, see sample_cell
/// for `dv`), Unobserved (a voxel has fewer than `min_weight` observations) or Absent (a corner's
/// block is not stored at this level).
HIVOX_HD HIVOX_DEVICE_NOINLINE inline CellRead read_trilinear(const MapView& map,
                                                              const int32_t blocks[8],
                                                              const CellCoords& cell,
                                                              int min_weight, TsdfSample* out,
                                                              const Vec3f* dv = nullptr) {
  float v[8];
  int min_w;
  if (!read_cell(map, blocks, cell.local, v, &min_w)) return CellRead::Absent;
  if (min_w < min_weight) return CellRead::Unobserved;
  const int nearest = sample_cell(v, cell.t, dv, out);
  out->nearest_index = cell_corner(blocks, cell.local, nearest, &out->nearest_ptr);
  return CellRead::Sampled;
}

/// The general case of `sample_trilinear`: the 8 voxels of `cell` span several blocks, and some
/// may be stored at another level. `neighbours` (optional) remembers the blocks around the cell's
/// block between calls. `dv` (optional): as in sample_cell, the ray's crossing inside the cell is
/// looked for on the interpolant the cell takes (trilinear, or the irregular one across levels),
/// so that a ray near a level boundary ends its search in one sample as elsewhere.
HIVOX_HD HIVOX_NOINLINE inline bool sample_trilinear_across_blocks(
    const MapView& map, BlockLookupCache& cache, int level, const CellCoords& cell, int min_weight,
    TsdfSample* out, NeighbourBlocks* neighbours = nullptr, const Vec3f* dv = nullptr) {
  const Vec3i& base = cell.base;
  const Vec3f& t = cell.t;
  const Vec3i& local = cell.local;
  // The 8 voxels span 2, 4 or 8 blocks: look each distinct block up once.
  int32_t own[8];
  const int32_t* blocks = own;
  if (neighbours != nullptr)
    blocks = neighbours->get(map, cache, level, cell.block, cell.span());
  else
    neighbour_blocks(map, cache, level, cell.block, cell.span(), own);
  // Usually every block the cell reaches into is stored at this level too.
  const CellRead read = read_trilinear(map, blocks, cell, min_weight, out, dv);
  if (read != CellRead::Absent) return read == CellRead::Sampled;
  if (map.levels == 1) return false;  // a corner's block is absent, and no other level has it
#if !defined(__CUDA_ARCH__)
  ++cache.cross_level_cells;
#endif
  float v[8];
  Vec3f pos[8];
  int32_t ptrs[8];
  int index[8];
  bool regular = true;
  for (int c = 0; c < 8; ++c) {
    const int ox = c & 1, oy = (c >> 1) & 1, oz = c >> 2;
    const Vec3i g{base.x + ox, base.y + oy, base.z + oz};
    int32_t ptr;
    int i = cell_corner(blocks, local, c, &ptr);
    pos[c] = to_float(g);
    if (ptr < 0) {  // this corner's region is stored at another level (or nowhere)
      Vec3f where;
      if (!corner_from_other_level(map, cache, level, g, c, &ptr, &i, &where)) return false;
      regular = regular && where == pos[c];
      pos[c] = where;
    }
    const TsdfVoxel vox = map.tsdf[static_cast<int64_t>(ptr) * kBlockVoxels + i];
    if (vox.weight < min_weight) return false;
    v[c] = tsdf_to_float(vox.tsdf);
    ptrs[c] = ptr;
    index[c] = i;
  }
#if !defined(__CUDA_ARCH__)
  cache.irregular_cells += !regular;
#endif
  int nearest;  // the corner nearest to the point the sample describes
  IrregularInterpolant in;
  if (!regular && solve_irregular(pos, v, &in)) {
    Vec3f q = cell.q - in.origin;
    nearest = nearest_corner(t);
    out->crossing_dz = kNoCrossing;
    if (dv != nullptr) {
      float p[4], dz;
      Vec3f t_hit;
      in.along_ray(q, *dv, p);
      if (crossing_on_ray(p[0], p[1], p[2], p[3], t, *dv, inverse_direction(*dv), &dz, &t_hit)) {
        out->crossing_dz = dz;
        q = q + (t_hit - t);
        nearest = nearest_corner(t_hit);
      }
    }
    out->f = in.at(q, &out->gradient);
  } else {
    nearest = sample_cell(v, t, dv, out);  // a regular cell, or degenerate positions
  }
  out->nearest_ptr = ptrs[nearest];
  out->nearest_index = index[nearest];
  return true;
}

/// Interpolates the TSDF at `p_w` from the 8 voxels of `level` around it: trilinear when they
/// are all stored at `level` (the common case, and the fast path when they share one block);
/// where the cell reaches into a region stored at another level, the corners take that level's
/// samples and the irregular-grid interpolant through their actual positions is used
/// (trilinear on their values if the positions are degenerate). Fails (returns false) when a
/// corner is not stored at any level or has fewer than `min_weight` observations: unknown space
/// must never look like surface. Given the direction `ray_d` (metres per unit of ray parameter)
/// of a ray through `p_w`, the cell (of either kind) also gives the ray's crossing inside it (see
/// TsdfSample::crossing_dz).
HIVOX_HD HIVOX_DEVICE_NOINLINE inline bool sample_trilinear(
    const MapView& map, BlockLookupCache& cache, int level, const Vec3f& p_w, int min_weight,
    TsdfSample* out, const Vec3i& known_block = Vec3i{INT_MIN, 0, 0}, int32_t known_ptr = kPtrEmpty,
    NeighbourBlocks* neighbours = nullptr, const Vec3f* ray_d = nullptr) {
  const CellCoords cell = cell_at(map.level[level], p_w);
  Vec3f dv;
  if (ray_d != nullptr) dv = *ray_d * map.level[level].inv_voxel_size;
  const Vec3f* dv_or_null = ray_d != nullptr ? &dv : nullptr;
  if (!cell.spans_blocks()) {
    // Most samples: the 8 voxels lie in one block (often the caller's).
    const Vec3i& block = cell.block;
    const Vec3i& local = cell.local;
    float v[8];
    const int32_t ptr = block == known_block ? known_ptr : cache.find(map, level, block);
    if (ptr < 0) return false;
    const TsdfVoxel* b = map.tsdf + static_cast<int64_t>(ptr) * kBlockVoxels;
    const int i0 = voxel_index(local.x, local.y, local.z);
    constexpr int kY = kBlockSide, kZ = kBlockSide * kBlockSide;
    const int offsets[8] = {0, 1, kY, kY + 1, kZ, kZ + 1, kZ + kY, kZ + kY + 1};
    int min_w = 65535;
    for (int c = 0; c < 8; ++c) {
      const TsdfVoxel vox = b[i0 + offsets[c]];
      min_w = vox.weight < min_w ? vox.weight : min_w;
      v[c] = tsdf_to_float(vox.tsdf);
    }
    if (min_w < min_weight) return false;
    out->nearest_ptr = ptr;
    out->nearest_index = i0 + offsets[sample_cell(v, cell.t, dv_or_null, out)];
    return true;
  }
  if (neighbours != nullptr) {  // the usual case, inline: every corner stored at this level
    const CellRead read =
        read_trilinear(map, neighbours->get(map, cache, level, cell.block, cell.span()), cell,
                       min_weight, out, dv_or_null);
    if (read != CellRead::Absent) return read == CellRead::Sampled;
  }
  return sample_trilinear_across_blocks(map, cache, level, cell, min_weight, out, neighbours,
                                        dv_or_null);
}

/// F(p + h e_k) for k = x, y, z (h: the voxel size of `level`): the trilinear samples one voxel
/// beyond `p_w` along each axis, as three `sample_trilinear` calls would give them, with at most
/// one look-up per block, when every voxel they need is stored at `level`. Returns false
/// otherwise (the caller samples one by one, across levels) or when a needed voxel has fewer
/// than `min_weight` observations.
HIVOX_HD HIVOX_DEVICE_NOINLINE inline bool samples_one_voxel_ahead(const MapView& map,
                                                                   BlockLookupCache& cache,
                                                                   int level, const Vec3f& p_w,
                                                                   int min_weight, Vec3f* ahead) {
  const CellCoords cell = cell_at(map.level[level], p_w);
  const Vec3i& local = cell.local;
  // The voxels base + [0, 2]^3 span one or two blocks per axis.
  int32_t blocks[8];
  neighbour_blocks(map, cache, level, cell.block, {local.x >= 6, local.y >= 6, local.z >= 6},
                   blocks);
  for (int k = 0; k < 3; ++k) {
    float v[8];
    int min_w;
    const Vec3i origin{local.x + (k == 0), local.y + (k == 1), local.z + (k == 2)};
    if (!read_cell(map, blocks, origin, v, &min_w) || min_w < min_weight) return false;
    Vec3f unused;
    (*ahead)[k] = interpolate_trilinear(v, cell.t, &unused);
  }
  return true;
}

/// The cell of level `coarse` around lattice point `g` of the finer `level` (global voxel
/// coordinates of each): its lowest corner `base` on the coarse lattice and g's fractions `t` in
/// it, exact (the levels' voxel sizes differ by a power of two).
struct CoarserCell {
  Vec3i base;
  Vec3f t;
  /// Corner c of the cell (c = cx | cy << 1 | cz << 2), on the coarse lattice.
  HIVOX_HD Vec3i corner(int c) const {
    return {base.x + (c & 1), base.y + ((c >> 1) & 1), base.z + (c >> 2)};
  }
  /// Corner c's trilinear weight at g: 0 for a corner g does not reach (g on a face, an edge or
  /// a coarse lattice point reads only the corners there).
  HIVOX_HD float weight(int c) const {
    const float wx = (c & 1) ? t.x : 1.0f - t.x, wy = ((c >> 1) & 1) ? t.y : 1.0f - t.y,
                wz = (c >> 2) ? t.z : 1.0f - t.z;
    return wx * wy * wz;
  }
};
HIVOX_HD inline CoarserCell coarser_cell(int level, const Vec3i& g, int coarse) {
  const int k = 1 << (coarse - level);
  CoarserCell cell;
  cell.base = {floor_div(g.x, k), floor_div(g.y, k), floor_div(g.z, k)};
  const float inv_k = 1.0f / static_cast<float>(k);  // exact: k is a power of two
  cell.t = {static_cast<float>(g.x - cell.base.x * k) * inv_k,
            static_cast<float>(g.y - cell.base.y * k) * inv_k,
            static_cast<float>(g.z - cell.base.z * k) * inv_k};
  return cell;
}

/// The TSDF at lattice point `g` of `level` as the coarser level `coarse` represents it: the
/// trilinear interpolant of that level's cell around the point, with exact fractions (a point
/// on a coarse face or edge reads only the corners of that face or edge, a coarse lattice point
/// only its own voxel). This is what a coarse cell's marching cubes sees on its faces, so a
/// finer grid that takes these values where it touches the coarse region meets its surface.
/// Corners inside finer regions are read there exactly. Fails when a corner that contributes
/// is not stored or has fewer than `min_weight` observations; `nearest_ptr`/`nearest_index`
/// receive the contributing voxel of the largest interpolation weight.
HIVOX_HD HIVOX_DEVICE_NOINLINE inline bool sample_on_coarser_lattice(
    const MapView& map, BlockLookupCache& cache, int level, const Vec3i& g, int coarse,
    float min_weight, float* f, int32_t* nearest_ptr, int* nearest_index) {
  const CoarserCell cell = coarser_cell(level, g, coarse);
  float v[8];
  float best = -1.0f;
  for (int c = 0; c < 8; ++c) {
    const float w = cell.weight(c);
    v[c] = 0.0f;
    if (w == 0.0f) continue;
    int32_t ptr;
    Vec3i voxel;
    if (lattice_voxel(map, cache, coarse, cell.corner(c), &ptr, &voxel) < 0) return false;
    const int index = local_voxel_index(voxel);
    const TsdfVoxel vox = map.tsdf[static_cast<int64_t>(ptr) * kBlockVoxels + index];
    if (static_cast<float>(vox.weight) < min_weight) return false;
    v[c] = tsdf_to_float(vox.tsdf);
    if (w > best) {
      best = w;
      *nearest_ptr = ptr;
      *nearest_index = index;
    }
  }
  Vec3f unused;
  *f = interpolate_trilinear(v, cell.t, &unused);
  return true;
}

/// The TSDF at `p_w`, at whatever level stores it (with `ray_d`: see sample_trilinear), searched
/// for from `start_level` (see locate_block: the level of a sample near it, where there is one).
HIVOX_HD HIVOX_DEVICE_NOINLINE inline bool sample_tsdf(const MapView& map, BlockLookupCache& cache,
                                                       const Vec3f& p_w, int min_weight,
                                                       TsdfSample* out, int* level,
                                                       const Vec3f* ray_d = nullptr,
                                                       int start_level = -1) {
  Vec3i pos;
  const int32_t ptr = locate_block(map, cache, p_w, level, &pos, start_level);
  if (ptr < 0) return false;
  return sample_trilinear(map, cache, *level, p_w, min_weight, out, pos, ptr, nullptr, ray_d);
}

}  // namespace hivox::kernels

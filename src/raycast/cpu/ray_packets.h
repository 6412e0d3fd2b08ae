#pragma once
// The CPU driver's ray packets. The hinted rays of a tile advance together, one step of the
// per-ray search at a time (HintSearch, CrossingBracket, the normal's samples one voxel ahead),
// and each step's TSDF samples are interpolated in one loop over the packet that the compiler
// vectorizes with gathers, instead of one branchy call per ray. Where a step's points are stored
// at one level (always, in a single-level map), their cells are addressed (which block, which
// voxels) in vectorized loops as well, from a box of blocks looked up once; otherwise addressing
// is scalar and uses the per-ray kernels' look-ups. A cell that reaches into another level is
// sampled by the per-ray kernel itself. A packet therefore finds what the per-ray search finds,
// up to float rounding (the vectorized loop may fuse multiplies and adds where the scalar code
// does not). A GPU driver runs the per-ray kernels, one ray per thread.

#include <climits>
#include <cmath>
#include <cstdint>

#include "hivox/map/map_view.h"
#include "map/sample_kernels.h"

namespace hivox::kernels {

/// Trilinear cells interpolated together: per cell, the pool indices (block * 512 + voxel) of
/// its 8 voxels (corner c = (c & 1, (c >> 1) & 1, c >> 2)) and the fractional position.
template <int kCapacity>
struct CellBatch {
  static constexpr int kLanes = 16;  ///< of the widest vectors (AVX-512: 16 floats)
  alignas(64) int32_t voxel[8][kCapacity];
  alignas(64) float tx[kCapacity];
  alignas(64) float ty[kCapacity];
  alignas(64) float tz[kCapacity];
  // The ray through each cell's point, in cell units per unit of ray parameter, and its inverse
  // (for interpolate<true>, see crossing_in_cell).
  alignas(64) float dvx[kCapacity];
  alignas(64) float dvy[kCapacity];
  alignas(64) float dvz[kCapacity];
  alignas(64) float inv_dvx[kCapacity];
  alignas(64) float inv_dvy[kCapacity];
  alignas(64) float inv_dvz[kCapacity];
  // Outputs of interpolate().
  alignas(64) float f[kCapacity];
  alignas(64) float gx[kCapacity];
  alignas(64) float gy[kCapacity];
  alignas(64) float gz[kCapacity];
  alignas(64) int32_t nearest[kCapacity];    ///< pool index of the voxel nearest to the point
  alignas(64) int32_t observed[kCapacity];   ///< every corner has the minimum weight (0 or 1)
  alignas(64) float crossing_dz[kCapacity];  ///< TsdfSample::crossing_dz

  /// Cell `i` with its lowest voxel at `origin`, counted from the first of `blocks` (see
  /// neighbour_blocks). Returns false when a corner's block is not stored at this level.
  bool set_across(int i, const int32_t blocks[8], const Vec3i& origin, const Vec3f& t) {
    int32_t missing = 0;
    for (int c = 0; c < 8; ++c) {
      int32_t ptr;
      const int index = cell_corner(blocks, origin, c, &ptr);
      missing |= ptr;  // negative when any is
      voxel[c][i] = ptr * kBlockVoxels + index;
    }
    set_t(i, t);
    return missing >= 0;
  }
  /// A cell that is not read (its result is ignored): any valid voxel will do.
  void set_unused(int i) {
    for (int c = 0; c < 8; ++c) voxel[c][i] = 0;
    set_t(i, Vec3f{});
    set_ray(i, Vec3f{}, Vec3f{});
  }
  void set_ray(int i, const Vec3f& dv, const Vec3f& inv_dv) {
    dvx[i] = dv.x;
    dvy[i] = dv.y;
    dvz[i] = dv.z;
    inv_dvx[i] = inv_dv.x;
    inv_dvy[i] = inv_dv.y;
    inv_dvz[i] = inv_dv.z;
  }
  void set_t(int i, const Vec3f& t) {
    tx[i] = t.x;
    ty[i] = t.y;
    tz[i] = t.z;
  }

  /// Interpolates cells [0, n): the values, gradients and nearest voxels `sample_trilinear`
  /// gives, in one vectorized loop; `kWithRay`: given the rays (set_ray), as it gives them with
  /// a ray (at the crossing inside the cell where there is one).
  template <bool kWithRay>
  void interpolate(const TsdfVoxel* pool, int n, int min_weight) {
    // Whole vectors only: the loop's scalar remainder would cost more than the padding.
    static_assert(kCapacity % kLanes == 0);
    for (; n % kLanes != 0; ++n) set_unused(n);
    // The voxel's TSDF and weight as one 32-bit word (int16 TSDF low, uint16 weight high).
    const uint32_t* words = reinterpret_cast<const uint32_t*>(pool);
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC ivdep
#endif
    for (int i = 0; i < n; ++i) {
      float v[8];
      int32_t index[8];
      uint32_t min_w = 0xFFFFu;
      for (int c = 0; c < 8; ++c) {
        index[c] = voxel[c][i];
        const uint32_t word = words[index[c]];
        const uint32_t w = word >> 16;
        min_w = w < min_w ? w : min_w;
        v[c] = static_cast<float>(tsdf_of_word(word)) * (1.0f / kTsdfScale);
      }
      Vec3f t{tx[i], ty[i], tz[i]};
      crossing_dz[i] = kNoCrossing;
      if constexpr (kWithRay) {
        float dz;
        Vec3f t_hit;
        const bool crossing = crossing_in_cell(v, t, {dvx[i], dvy[i], dvz[i]},
                                               {inv_dvx[i], inv_dvy[i], inv_dvz[i]}, &dz, &t_hit);
        crossing_dz[i] = crossing ? dz : kNoCrossing;
        t.x = crossing ? t_hit.x : t.x;
        t.y = crossing ? t_hit.y : t.y;
        t.z = crossing ? t_hit.z : t.z;
      }
      Vec3f g;
      f[i] = interpolate_trilinear(v, t, &g);
      gx[i] = g.x;
      gy[i] = g.y;
      gz[i] = g.z;
      observed[i] = min_w >= static_cast<uint32_t>(min_weight);
      // The corner nearest to t, by selects along x, y, z (indexing the corners by the computed
      // number would keep the loop from vectorizing).
      const bool nx = t.x >= 0.5f, ny = t.y >= 0.5f, nz = t.z >= 0.5f;
      const int32_t e0 = nx ? index[1] : index[0], e1 = nx ? index[3] : index[2];
      const int32_t e2 = nx ? index[5] : index[4], e3 = nx ? index[7] : index[6];
      const int32_t f0 = ny ? e1 : e0, f1 = ny ? e3 : e2;
      nearest[i] = nz ? f1 : f0;
    }
  }

  /// Cell `i`'s result as a TsdfSample.
  TsdfSample sample(int i) const {
    TsdfSample s;
    s.f = f[i];
    s.gradient = {gx[i], gy[i], gz[i]};
    s.nearest_ptr = nearest[i] / kBlockVoxels;
    s.nearest_index = nearest[i] % kBlockVoxels;
    s.crossing_dz = crossing_dz[i];
    return s;
  }
};

/// Whether pool indices (block * 512 + voxel) of this map fit the packets' 32-bit gathers.
inline bool packets_can_address(const MapView& map) {
  return static_cast<int64_t>(map.block_capacity) * kBlockVoxels <= INT32_MAX;
}

/// The blocks of one level in a box of block coordinates [lo, lo + size), looked up once for
/// many cells: a packet's cells then find their blocks by index arithmetic, in vectorized loops.
struct BlockBox {
  static constexpr int kCapacity = 64;
  int level = -1;  ///< -1: empty
  Vec3i lo, size;
  alignas(64) int32_t ptr[kCapacity];

  /// Makes the box hold blocks [lo2, hi2] (inclusive) of level `l`: true when it already does
  /// or now does; false when they are more than kCapacity.
  bool cover(const MapView& map, BlockLookupCache& cache, int l, const Vec3i& lo2,
             const Vec3i& hi2) {
    if (l == level && lo2.x >= lo.x && lo2.y >= lo.y && lo2.z >= lo.z && hi2.x < lo.x + size.x &&
        hi2.y < lo.y + size.y && hi2.z < lo.z + size.z)
      return true;
    const Vec3i s{hi2.x - lo2.x + 1, hi2.y - lo2.y + 1, hi2.z - lo2.z + 1};
    if (s.x > kCapacity || s.y > kCapacity || s.z > kCapacity || s.x * s.y * s.z > kCapacity)
      return false;
    level = l;
    lo = lo2;
    size = s;
    for (int z = 0; z < s.z; ++z)
      for (int y = 0; y < s.y; ++y)
        for (int x = 0; x < s.x; ++x)
          ptr[(z * s.y + y) * s.x + x] = cache.find(map, l, {lo.x + x, lo.y + y, lo.z + z});
    return true;
  }
};

/// Addresses the cells of level `l` around `n` points together, in vectorized loops: per point
/// `kPerPoint` cells go to `cells`, cell k of point i at k * n + i (1: the cell around the point;
/// 3: the cells one voxel ahead along x, y, z, as samples_one_voxel_ahead reads them);
/// `complete[j]` is false where a corner's block is not stored at `l` (the cell is then addressed
/// at voxel 0, to be ignored). Returns false, addressing nothing, when the cells reach into more
/// blocks than a BlockBox holds.
template <int kPerPoint, int kCapacity>
bool address_cells_one_level(const MapView& map, BlockLookupCache& cache, BlockBox& box, int l,
                             int n, const Vec3f* points, CellBatch<kCapacity>& cells,
                             int32_t* complete) {
  static_assert(kPerPoint == 1 || kPerPoint == 3);
  constexpr int kPoints = kCapacity / kPerPoint;
  const float inv_voxel = map.level[l].inv_voxel_size;
  alignas(64) int32_t bx[kPoints], by[kPoints], bz[kPoints];
  alignas(64) int32_t lx[kPoints], ly[kPoints], lz[kPoints];
  int32_t lo_x = INT_MAX, lo_y = INT_MAX, lo_z = INT_MAX;
  int32_t hi_x = INT_MIN, hi_y = INT_MIN, hi_z = INT_MIN;
  // As cell_at: the cell's lowest voxel, its block and place there, the fractional position.
  const float* xyz = &points[0].x;  // Vec3f is three packed floats
  for (int i = 0; i < n; ++i) {
    const float qx = xyz[3 * i] * inv_voxel, qy = xyz[3 * i + 1] * inv_voxel,
                qz = xyz[3 * i + 2] * inv_voxel;
    const int32_t gx = static_cast<int32_t>(std::floor(qx));
    const int32_t gy = static_cast<int32_t>(std::floor(qy));
    const int32_t gz = static_cast<int32_t>(std::floor(qz));
    cells.tx[i] = qx - static_cast<float>(gx);
    cells.ty[i] = qy - static_cast<float>(gy);
    cells.tz[i] = qz - static_cast<float>(gz);
    bx[i] = gx >> 3;
    by[i] = gy >> 3;
    bz[i] = gz >> 3;
    lx[i] = gx & 7;
    ly[i] = gy & 7;
    lz[i] = gz & 7;
    lo_x = bx[i] < lo_x ? bx[i] : lo_x;
    lo_y = by[i] < lo_y ? by[i] : lo_y;
    lo_z = bz[i] < lo_z ? bz[i] : lo_z;
    hi_x = bx[i] > hi_x ? bx[i] : hi_x;
    hi_y = by[i] > hi_y ? by[i] : hi_y;
    hi_z = bz[i] > hi_z ? bz[i] : hi_z;
  }
  for (int k = 1; k < kPerPoint; ++k)
    for (int i = 0; i < n; ++i) {
      cells.tx[k * n + i] = cells.tx[i];
      cells.ty[k * n + i] = cells.ty[i];
      cells.tz[k * n + i] = cells.tz[i];
    }
  // A cell's voxels reach at most one block beyond the block of its lowest voxel (the cells
  // ahead start one voxel further, at most at local 8 + 1).
  if (!box.cover(map, cache, l, {lo_x, lo_y, lo_z}, {hi_x + 1, hi_y + 1, hi_z + 1})) return false;
  const int32_t sx = box.size.x, sxy = box.size.x * box.size.y;
  const int32_t origin = box.lo.x + box.lo.y * sx + box.lo.z * sxy;
  const int32_t* ptrs = box.ptr;
  for (int k = 0; k < kPerPoint; ++k) {
    const int32_t dx = kPerPoint == 3 && k == 0, dy = kPerPoint == 3 && k == 1,
                  dz = kPerPoint == 3 && k == 2;
    int32_t* voxel[8];
    for (int c = 0; c < 8; ++c) voxel[c] = cells.voxel[c] + k * n;
    int32_t* done = complete + k * n;
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC ivdep
#endif
    for (int i = 0; i < n; ++i) {
      const int32_t row = bx[i] + by[i] * sx + bz[i] * sxy - origin;
      const int32_t ox = lx[i] + dx, oy = ly[i] + dy, oz = lz[i] + dz;
      int32_t missing = 0;
      HIVOX_UNROLL(8)
      for (int c = 0; c < 8; ++c) {
        const int32_t x = ox + (c & 1), y = oy + ((c >> 1) & 1), z = oz + (c >> 2);
        const int32_t ptr = ptrs[row + (x >> 3) + (y >> 3) * sx + (z >> 3) * sxy];
        missing |= ptr;  // negative when any is
        voxel[c][i] = (ptr < 0 ? 0 : ptr) * kBlockVoxels + voxel_index(x & 7, y & 7, z & 7);
      }
      done[i] = missing >= 0;
    }
  }
  return true;
}

/// The look-ups of consecutive samples of a packet, which mostly fall into the block of the
/// sample before (neighbouring rays, steps along one ray): where the last point was found, the
/// 2x2x2 blocks from the last cell's block up, and the box of blocks of the last step's cells.
struct PacketLookups {
  int level = -1;  ///< of the last located point (-1: none yet)
  Vec3i pos;
  int32_t ptr = kPtrEmpty;
  NeighbourBlocks cells;  ///< around the last cell's block
  BlockBox box;           ///< the blocks around the last step's cells, when they share a level

  /// locate_block, remembering the last result: a point in the same block at the level where
  /// the last search ended has the same coarser blocks above it, so the search ends there too.
  int32_t locate(const MapView& map, BlockLookupCache& cache, const Vec3f& p, int* l, Vec3i* b) {
    if (level < 0 || !(block_of_point(map.level[level], p) == pos))
      ptr = locate_block(map, cache, p, &level, &pos);
    *l = level;
    *b = pos;
    return ptr;
  }
};

/// `sample_tsdf` at `n` points at once: `sampled[i]`, `out[i]` and `level[i]` are what
/// sample_tsdf(points[i], &dirs[i]) gives (without `dirs`, nullptr: sample_tsdf(points[i])).
/// `inv_dirs` (with `dirs`): inverse_direction(dirs[i]).
template <int kCapacity>
void sample_tsdf_packet(const MapView& map, BlockLookupCache& cache, PacketLookups& lookups, int n,
                        const Vec3f* points, const Vec3f* dirs, const Vec3f* inv_dirs,
                        int min_weight, CellBatch<kCapacity>& cells, TsdfSample* out, int* level,
                        bool* sampled) {
  // The block storing each point (where the search from the coarsest level ends; negative:
  // none). On one level there is nothing to search: a point whose block is absent has a cell
  // with an absent corner.
  int32_t located[kCapacity];
  const bool one_level = map.levels == 1;  // read once: the stores below may alias it
  int common = one_level ? 0 : -1;         // the level of every point found (-2: they differ)
  for (int i = 0; i < n; ++i) {
    level[i] = 0;
    located[i] = 0;
  }
  for (int i = 0; i < n && !one_level; ++i) {
    Vec3i pos;
    located[i] = lookups.locate(map, cache, points[i], &level[i], &pos);
    if (located[i] >= 0) common = common == -1 || common == level[i] ? level[i] : -2;
  }
  // The cells: together where the points found share a level, else one by one.
  int32_t complete[kCapacity];
  if (common < 0 ||
      !address_cells_one_level<1>(map, cache, lookups.box, common, n, points, cells, complete)) {
    for (int i = 0; i < n; ++i) {
      Vec3i pos;
      located[i] = lookups.locate(map, cache, points[i], &level[i], &pos);
      complete[i] = false;
      if (located[i] >= 0) {
        // As sample_trilinear: the cell, and the blocks its 8 voxels lie in.
        const CellCoords cell = cell_at(map.level[level[i]], points[i]);
        complete[i] = cells.set_across(i, lookups.cells.get(map, cache, level[i], cell.block),
                                       cell.local, cell.t);
      }
      if (!complete[i]) cells.set_unused(i);
    }
  }
  if (dirs != nullptr) {
    for (int i = 0; i < n; ++i) {
      const LevelView& lv = map.level[level[i]];
      cells.set_ray(i, dirs[i] * lv.inv_voxel_size, inv_dirs[i] * lv.voxel_size_m);
    }
    cells.template interpolate<true>(map.tsdf, n, min_weight);
  } else {
    cells.template interpolate<false>(map.tsdf, n, min_weight);
  }
  for (int i = 0; i < n; ++i) {
    sampled[i] = false;
    if (located[i] < 0) continue;
    if (complete[i]) {
      sampled[i] = cells.observed[i] != 0;
      if (sampled[i]) out[i] = cells.sample(i);
      continue;
    }
    // A cell inside one block that is absent is unknown; one that reaches into a region stored
    // at another level (or nowhere) is sampled there.
    const CellCoords cell = cell_at(map.level[level[i]], points[i]);
    if (cell.spans_blocks()) {
      const Vec3f dv{cells.dvx[i], cells.dvy[i], cells.dvz[i]};  // as set_ray set it
      sampled[i] = sample_trilinear_across_blocks(map, cache, level[i], cell, min_weight, &out[i],
                                                  &lookups.cells, dirs != nullptr ? &dv : nullptr);
    }
  }
}

/// `samples_one_voxel_ahead` for `n` surface points at once (point `points[i]` at level
/// `level[i]`): `ok[i]` and `ahead[i]` are what it gives. `cells` holds 3 cells per point, cell
/// k of point i at k * n + i.
template <int kCapacity>
void samples_one_voxel_ahead_packet(const MapView& map, BlockLookupCache& cache,
                                    PacketLookups& lookups, int n, const Vec3f* points,
                                    const int* level, int min_weight, CellBatch<kCapacity>& cells,
                                    Vec3f* ahead, bool* ok) {
  if (n == 0) return;
  bool common = true;
  for (int i = 1; i < n; ++i) common = common && level[i] == level[0];
  int32_t complete[kCapacity];
  if (!common ||
      !address_cells_one_level<3>(map, cache, lookups.box, level[0], n, points, cells, complete)) {
    for (int i = 0; i < n; ++i) {
      const CellCoords cell = cell_at(map.level[level[i]], points[i]);
      const int32_t* blocks = lookups.cells.get(map, cache, level[i], cell.block);
      const Vec3i& local = cell.local;
      for (int k = 0; k < 3; ++k) {
        const Vec3i origin{local.x + (k == 0), local.y + (k == 1), local.z + (k == 2)};
        complete[k * n + i] = cells.set_across(k * n + i, blocks, origin, cell.t);
        if (!complete[k * n + i]) cells.set_unused(k * n + i);
      }
    }
  }
  cells.template interpolate<false>(map.tsdf, 3 * n, min_weight);
  for (int i = 0; i < n; ++i) {
    ok[i] = true;
    for (int k = 0; k < 3; ++k) {
      ok[i] = ok[i] && complete[k * n + i] && cells.observed[k * n + i];
      ahead[i][k] = cells.f[k * n + i];
    }
  }
}

}  // namespace hivox::kernels

#pragma once
// The CPU driver's ray packets. The hinted rays of a tile advance together, one step of the
// per-ray search at a time (HintSearch, CrossingBracket, the normal's samples one voxel ahead),
// and each step's TSDF samples are interpolated in one loop over the packet that the compiler
// vectorizes with gathers, instead of one branchy call per ray. Addressing (which block, which
// voxels) stays scalar and uses the per-ray kernels' look-ups; a cell that reaches into another
// level is sampled by the per-ray kernel itself. A packet therefore finds what the per-ray search
// finds, up to float rounding (the vectorized loop may fuse multiplies and adds where the scalar
// code does not). A GPU driver runs the per-ray kernels, one ray per thread.

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
  // Outputs of interpolate().
  alignas(64) float f[kCapacity];
  alignas(64) float gx[kCapacity];
  alignas(64) float gy[kCapacity];
  alignas(64) float gz[kCapacity];
  alignas(64) int32_t nearest[kCapacity];   ///< pool index of the voxel nearest to the point
  alignas(64) uint8_t observed[kCapacity];  ///< every corner has the minimum weight

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
  }
  void set_t(int i, const Vec3f& t) {
    tx[i] = t.x;
    ty[i] = t.y;
    tz[i] = t.z;
  }

  /// Interpolates cells [0, n): the values, gradients and nearest voxels `sample_trilinear`
  /// gives, in one vectorized loop.
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
        v[c] = tsdf_to_float(static_cast<int16_t>(word & 0xFFFFu));
      }
      const Vec3f t{tx[i], ty[i], tz[i]};
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
    return s;
  }
};

/// Whether pool indices (block * 512 + voxel) of this map fit the packets' 32-bit gathers.
inline bool packets_can_address(const MapView& map) {
  return static_cast<int64_t>(map.block_capacity) * kBlockVoxels <= INT32_MAX;
}

/// The look-ups of consecutive samples of a packet, which mostly fall into the block of the
/// sample before (neighbouring rays, steps along one ray): where the last point was found, and
/// the 2x2x2 blocks from the last cell's block up (see neighbour_blocks).
struct PacketLookups {
  int level = -1;  ///< of the last located point (-1: none yet)
  Vec3i pos;
  int32_t ptr = kPtrEmpty;
  int cells_level = -1;  ///< of `cells_block` (-1: none yet)
  Vec3i cells_block;
  int32_t cells_ptrs[8];

  /// locate_block, remembering the last result: a point in the same block at the level where
  /// the last search ended has the same coarser blocks above it, so the search ends there too.
  int32_t locate(const MapView& map, BlockLookupCache& cache, const Vec3f& p, int* l, Vec3i* b) {
    if (level < 0 || !(block_of_point(map.level[level], p) == pos))
      ptr = locate_block(map, cache, p, &level, &pos);
    *l = level;
    *b = pos;
    return ptr;
  }
  /// The blocks of `l` from `block` up by 0 or 1 along each axis.
  const int32_t* neighbours(const MapView& map, BlockLookupCache& cache, int l,
                            const Vec3i& block) {
    if (l != cells_level || !(block == cells_block)) {
      neighbour_blocks(map, cache, l, block, {1, 1, 1}, cells_ptrs);
      cells_level = l;
      cells_block = block;
    }
    return cells_ptrs;
  }
};

/// `sample_tsdf` at `n` points at once: `sampled[i]`, `out[i]` and `level[i]` are what
/// sample_tsdf(points[i]) gives.
template <int kCapacity>
void sample_tsdf_packet(const MapView& map, BlockLookupCache& cache, PacketLookups& lookups, int n,
                        const Vec3f* points, int min_weight, CellBatch<kCapacity>& cells,
                        TsdfSample* out, int* level, bool* sampled) {
  bool gathered[kCapacity];
  for (int i = 0; i < n; ++i) {
    Vec3i pos;
    const int32_t ptr = lookups.locate(map, cache, points[i], &level[i], &pos);
    gathered[i] = false;
    sampled[i] = false;
    if (ptr < 0) {
      cells.set_unused(i);
      continue;
    }
    const int l = level[i];
    // As sample_trilinear: the cell, and the blocks its 8 voxels lie in.
    const CellCoords cell = cell_at(map.level[l], points[i]);
    const int32_t* blocks = lookups.neighbours(map, cache, l, cell.block);
    gathered[i] = cells.set_across(i, blocks, cell.local, cell.t);
    if (gathered[i]) continue;
    cells.set_unused(i);
    // A cell inside one block that is absent is unknown; one that reaches into a region
    // stored at another level (or nowhere) is sampled there.
    if (cell.spans_blocks())
      sampled[i] = sample_trilinear_across_blocks(map, cache, l, cell, min_weight, &out[i]);
  }
  cells.interpolate(map.tsdf, n, min_weight);
  for (int i = 0; i < n; ++i) {
    if (!gathered[i]) continue;
    sampled[i] = cells.observed[i] != 0;
    if (sampled[i]) out[i] = cells.sample(i);
  }
}

/// `samples_one_voxel_ahead` for `n` surface points at once (point `points[i]` at level
/// `level[i]`): `ok[i]` and `ahead[i]` are what it gives. `cells` holds 3 cells per point.
template <int kCapacity>
void samples_one_voxel_ahead_packet(const MapView& map, BlockLookupCache& cache,
                                    PacketLookups& lookups, int n, const Vec3f* points,
                                    const int* level, int min_weight, CellBatch<kCapacity>& cells,
                                    Vec3f* ahead, bool* ok) {
  for (int i = 0; i < n; ++i) {
    const CellCoords cell = cell_at(map.level[level[i]], points[i]);
    const int32_t* blocks = lookups.neighbours(map, cache, level[i], cell.block);
    const Vec3i& local = cell.local;
    ok[i] = true;
    for (int k = 0; k < 3; ++k) {
      const Vec3i origin{local.x + (k == 0), local.y + (k == 1), local.z + (k == 2)};
      if (!ok[i] || !cells.set_across(3 * i + k, blocks, origin, cell.t)) {
        ok[i] = false;
        cells.set_unused(3 * i + k);
      }
    }
  }
  cells.interpolate(map.tsdf, 3 * n, min_weight);
  for (int i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      ok[i] = ok[i] && cells.observed[3 * i + k] != 0;
      ahead[i][k] = cells.f[3 * i + k];
    }
  }
}

}  // namespace hivox::kernels

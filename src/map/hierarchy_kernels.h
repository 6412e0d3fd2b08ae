#pragma once
// The data side of the hierarchy's edits, written once for CPU and CUDA: children filled from a
// splitting parent, a merged parent from its children, and chains shortened when a child's entry
// empties.

#include <array>
#include <cstdint>

#include "hivox/core/atomic.h"
#include "hivox/core/hd.h"
#include "hivox/map/hierarchy_edit.h"
#include "hivox/map/map_view.h"
#include "map/sample_kernels.h"

namespace hivox::kernels {

// ---- split: children from the parent ---------------------------------------------------------

/// A weighted sum of voxels, as a split's interpolations take it: TSDF, weight and colour
/// (`coloured` stays true while every voxel added has a colour; colours are read only then).
struct VoxelBlend {
  float f = 0, w = 0;
  float r = 0, g = 0, b = 0, cw = 0;
  bool coloured = false;

  /// Adds `a` times `vox` and, while coloured, `*col`.
  HIVOX_HD void add(float a, const TsdfVoxel& vox, const ColorVoxel* col) {
    w += a * static_cast<float>(vox.weight);
    f += a * tsdf_to_float(vox.tsdf);
    if (coloured) {
      coloured = col->weight > 0;
      cw += a * static_cast<float>(col->weight);
      r += a * col->r;
      g += a * col->g;
      b += a * col->b;
    }
  }
  /// Adds `a` times another blend.
  HIVOX_HD void add(float a, const VoxelBlend& o) {
    w += a * o.w;
    f += a * o.f;
    if (coloured) {
      coloured = o.coloured;
      cw += a * o.cw;
      r += a * o.r;
      g += a * o.g;
      b += a * o.b;
    }
  }
};

/// What a coarser level stores at lattice point `g` of `level` (global voxel coordinates of
/// that level) where no block of `level` holds it: the TSDF, weight and colour (`color`, or none)
/// interpolated trilinearly at the same point from the voxels of the first coarser level that
/// stores the point's block (the point lies on that level's lattice or between its voxels).
/// False where no coarser level stores it, or a voxel the interpolation takes is missing or
/// unobserved.
HIVOX_HD inline bool value_from_coarser(const MapView& map, const TsdfVoxel* tsdf,
                                        const ColorVoxel* color, int level, const Vec3i& g,
                                        VoxelBlend* out) {
  int l;
  const int32_t holder =
      find_coarser_holder(map, level, block_of_voxel(g), &l,
                          [&](int at, const Vec3i& p) { return find_block_ptr(map.level[at], p); });
  if (holder < 0) return false;
  const CoarserCell cell = coarser_cell(level, g, l);
  const Vec3i base_block = block_of_voxel(cell.base);
  VoxelBlend v;
  v.coloured = color != nullptr;
  for (int c = 0; c < 8; ++c) {
    const float a = cell.weight(c);
    if (a == 0.0f) continue;  // a corner the point does not reach
    const Vec3i voxel = cell.corner(c);
    const Vec3i block = block_of_voxel(voxel);
    const int32_t ptr = block == base_block ? holder : find_block_ptr(map.level[l], block);
    if (ptr < 0) return false;
    const int64_t k = static_cast<int64_t>(ptr) * kBlockVoxels + local_voxel_index(voxel);
    if (tsdf[k].weight == 0) return false;
    v.add(a, tsdf[k], v.coloured ? &color[k] : nullptr);
  }
  *out = v;
  return true;
}

/// Voxel `i` of child `child` (offset (child & 1, (child >> 1) & 1, child >> 2)) of a splitting
/// parent: trilinear interpolation of the parent's voxels. `parent_blocks[d]` holds the parent's
/// block (d = 0) and its +x/+y/+z neighbours at the parent's level (d = dx | dy << 1 | dz << 2; a
/// negative ptr when absent), `neighbour_children[d][c]` the children one level down of a
/// neighbour that was split before (negative when none): the last half voxel of the parent
/// interpolates towards the neighbour's voxel, read at the parent's level or, when split, at the
/// same point one level down, or, where the neighbour's region is stored at a coarser level, at
/// the same point from that level (value_from_coarser: without it the children's last voxel
/// layer towards a coarser region stayed unobserved, a sliver rays stepped over). A child voxel
/// is observed only when every parent voxel its interpolation takes is observed: a value is not
/// extrapolated towards an unobserved or missing voxel (behind a surface seen at a grazing angle
/// that would leave a positive value inside the object, a false surface fine observations never
/// reach to correct). Weights are interpolated and scaled by `weight_scale`. Writes its colour to
/// `*color` when not null. `parent`: the splitting block (its position and level).
HIVOX_HD inline TsdfVoxel split_child_voxel(const MutableMapView& map, const BlockRef& parent,
                                            const int32_t parent_blocks[8],
                                            const int32_t neighbour_children[8][8], int child,
                                            int i, float weight_scale, ColorVoxel* color) {
  const int ox = child & 1, oy = (child >> 1) & 1, oz = child >> 2;
  const Vec3i j = voxel_coords(i);
  // Parent coordinate of the child voxel: (8 o + j) / 2, i.e. a parent voxel or a midpoint.
  const int qx = 4 * ox + (j.x >> 1), qy = 4 * oy + (j.y >> 1), qz = 4 * oz + (j.z >> 1);
  const int hx = j.x & 1, hy = j.y & 1, hz = j.z & 1;  // 1: halfway to the next parent voxel
  VoxelBlend sum;
  sum.coloured = color != nullptr && map.color != nullptr;
  bool observed = true;
  for (int c = 0; c < 8 && observed; ++c) {
    const int cx = c & 1, cy = (c >> 1) & 1, cz = c >> 2;
    if ((cx > hx) | (cy > hy) | (cz > hz)) continue;  // corner not involved
    const float a = (hx ? 0.5f : 1.0f) * (hy ? 0.5f : 1.0f) * (hz ? 0.5f : 1.0f);
    const int px = qx + cx, py = qy + cy, pz = qz + cz;
    const int d = (px >> 3) | ((py >> 3) << 1) | ((pz >> 3) << 2);
    int32_t ptr = parent_blocks[d];
    int vi = voxel_index(px & 7, py & 7, pz & 7);
    if (ptr < 0 && d != 0) {
      // The neighbour was split: its child holds the same point one level down.
      const int fx = 2 * (px & 7), fy = 2 * (py & 7), fz = 2 * (pz & 7);
      ptr = neighbour_children[d][(fx >> 3) | ((fy >> 3) << 1) | ((fz >> 3) << 2)];
      vi = voxel_index(fx & 7, fy & 7, fz & 7);
    }
    if (ptr < 0 && d != 0) {
      // The neighbour's region is stored at a coarser level (or nowhere).
      const Vec3i lattice{parent.pos.x * kBlockSide + px, parent.pos.y * kBlockSide + py,
                          parent.pos.z * kBlockSide + pz};
      VoxelBlend coarse;
      observed = value_from_coarser(map.read, map.tsdf, sum.coloured ? map.color : nullptr,
                                    parent.level, lattice, &coarse);
      if (observed) sum.add(a, coarse);
      continue;
    }
    const int64_t k = static_cast<int64_t>(ptr) * kBlockVoxels + vi;
    observed = ptr >= 0 && map.tsdf[k].weight > 0;
    if (observed) sum.add(a, map.tsdf[k], sum.coloured ? &map.color[k] : nullptr);
  }
  TsdfVoxel v;
  if (observed) {
    v.tsdf = tsdf_from_float(sum.f);
    const float w = sum.w * weight_scale + 0.5f;
    v.weight = static_cast<uint16_t>(w < 1.0f ? 1.0f : w);
  }
  if (color != nullptr) {
    ColorVoxel cv;
    if (observed && sum.coloured) {
      cv.r = static_cast<uint8_t>(sum.r + 0.5f);
      cv.g = static_cast<uint8_t>(sum.g + 0.5f);
      cv.b = static_cast<uint8_t>(sum.b + 0.5f);
      const float w = sum.cw * weight_scale + 0.5f;
      cv.weight = static_cast<uint8_t>(w < 1.0f ? 1.0f : (w > 255.0f ? 255.0f : w));
    }
    *color = cv;
  }
  return v;
}

/// Fills every voxel of child `child` of a splitting parent (split_child_voxel) into pool block
/// `child_ptr`. Returns the child's surface summary.
HIVOX_HD inline BlockSurface fill_split_child(const MutableMapView& map, const BlockRef& parent,
                                              const int32_t parent_blocks[8],
                                              const int32_t neighbour_children[8][8], int child,
                                              int32_t child_ptr, float weight_scale) {
  TsdfVoxel* out = map.tsdf + static_cast<int64_t>(child_ptr) * kBlockVoxels;
  ColorVoxel* out_c =
      map.color ? map.color + static_cast<int64_t>(child_ptr) * kBlockVoxels : nullptr;
  for (int i = 0; i < kBlockVoxels; ++i)
    out[i] = split_child_voxel(map, parent, parent_blocks, neighbour_children, child, i,
                               weight_scale, out_c != nullptr ? out_c + i : nullptr);
  return block_surface(out);
}

/// The blocks a split of `parent` reads (fill_split_child's `parent_blocks` and
/// `neighbour_children`): its block and its +x/+y/+z neighbours at its level, and the children
/// one level down of the neighbours that are split.
HIVOX_HD inline void split_sources(const MapView& map, const BlockRef& parent,
                                   int32_t parent_blocks[8], int32_t neighbour_children[8][8]) {
  const LevelView& lv = map.level[parent.level];
  const LevelView& fine = map.level[parent.level - 1];
  for (int d = 0; d < kBlockChildren; ++d) {
    const Vec3i n{parent.pos.x + (d & 1), parent.pos.y + ((d >> 1) & 1), parent.pos.z + (d >> 2)};
    const int32_t ptr = d == 0 ? parent.ptr : find_block_ptr(lv, n);
    parent_blocks[d] = ptr >= 0 ? ptr : kPtrEmpty;
    for (int c = 0; c < kBlockChildren; ++c)
      neighbour_children[d][c] =
          ptr == kPtrSplit ? find_block_ptr(fine, child_block_pos(n, c)) : kPtrEmpty;
  }
}

/// The room splits take, handed out in order (host code): 8 pool blocks a split (the parent's
/// block comes back only afterwards) and, in the worst case, 8 overflow entries at the child
/// level. A split that finds too little waits.
struct SplitRoom {
  int64_t free_blocks = 0;
  std::array<int64_t, kMaxLevels> free_excess{};  ///< per level
  /// Takes the room of splitting a block of `level`; false (nothing taken) when it lacks.
  bool take(int level) {
    int64_t& excess = free_excess[static_cast<std::size_t>(level - 1)];
    if (free_blocks < kBlockChildren || excess < kBlockChildren) return false;
    free_blocks -= kBlockChildren;
    excess -= kBlockChildren;
    return true;
  }
};

// ---- merge: the parent from its children -----------------------------------------------------

/// Where a merged parent's voxel `i` comes from: child `*child` (c = cx | cy << 1 | cz << 2) of
/// the parent, at the returned voxel index -- child voxel 2 (i mod 4) of child i / 4 along each
/// axis, the sample at the same position.
HIVOX_HD inline int merged_voxel_source(int i, int* child) {
  const Vec3i p = voxel_coords(i);
  *child = (p.x >> 2) | ((p.y >> 2) << 1) | ((p.z >> 2) << 2);
  return voxel_index(2 * (p.x & 3), 2 * (p.y & 3), 2 * (p.z & 3));
}

/// Fills a merged parent block by subsampling its 8 children (`child_ptrs[c]`, c = cx | cy << 1 |
/// cz << 2; merged_voxel_source). A split followed by a merge gives back the parent exactly.
/// Returns the parent's surface summary.
HIVOX_HD inline BlockSurface fill_merged_parent(const MutableMapView& map,
                                                const int32_t child_ptrs[8], int32_t parent_ptr) {
  TsdfVoxel* out = map.tsdf + static_cast<int64_t>(parent_ptr) * kBlockVoxels;
  ColorVoxel* out_c =
      map.color ? map.color + static_cast<int64_t>(parent_ptr) * kBlockVoxels : nullptr;
  for (int i = 0; i < kBlockVoxels; ++i) {
    int child;
    const int src = merged_voxel_source(i, &child);
    const int64_t at = static_cast<int64_t>(child_ptrs[child]) * kBlockVoxels + src;
    out[i] = map.tsdf[at];
    if (out_c != nullptr) out_c[i] = map.color[at];
  }
  return block_surface(out);
}

/// Removes entry `e` (already Empty) from its chain when it is the chain's tail and lies in the
/// excess area, so that chains shrink only at their end; returns true when unlinked (the caller
/// returns it to the level's excess free list). Safe against other threads doing the same.
HIVOX_HD inline bool unlink_tail_entry(const MutableMapView& map, int level, int32_t e,
                                       const Vec3i& pos) {
  const MutableLevelView& lv = map.level[level];
  const uint32_t bucket_mask = map.read.level[level].bucket_mask;
  if (e <= static_cast<int32_t>(bucket_mask) || atomic_load(&lv.entries[e].next) != kNoEntry)
    return false;
  int32_t i = static_cast<int32_t>(block_hash(pos, bucket_mask));
  while (i != kNoEntry) {
    const int32_t next = atomic_load(&lv.entries[i].next);
    if (next == e) return atomic_cas(&lv.entries[i].next, e, kNoEntry) == e;
    i = next;
  }
  return false;
}

}  // namespace hivox::kernels

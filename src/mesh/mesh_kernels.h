#pragma once
// Marching-cubes math written once for the CPU and CUDA drivers: gathering a block with a
// one-to-two-voxel apron from its neighbours (at its level, or sampled from the level that
// stores them), the per-cell case, and the per-edge vertex (position, normal, colour).
//
// A block's cells are its 8x8x8 voxels taken as lower corners; a cell reaches one voxel into
// the +x/+y/+z neighbours. A block owns the 3 edges leaving each of its voxels in +x, +y, +z
// (local edge id = voxel_index * 3 + axis), so every edge of a level's grid inside its blocks
// has exactly one owner and a vertex on it is computed once. Edges starting in a region of
// another level have no owner at this level: each block using one computes it (identically).

#include <cstdint>

#include "hivox/core/hd.h"
#include "hivox/core/image.h"
#include "hivox/core/math.h"
#include "hivox/map/map_view.h"
#include "map/sample_kernels.h"
#include "mesh/mc_table.h"

namespace hivox::kernels {

/// Local coordinates covered by a padded block: [-1, 9] on each axis. Cells with lower corners
/// in [-1, 7] (the owned ones plus the -1 layer that shares owned edges) need [-1, 8]; central
/// differences at edge ends in [0, 8] need [-1, 9].
inline constexpr int kPadLo = -1;
inline constexpr int kPadSide = 11;
inline constexpr int kPadVoxels = kPadSide * kPadSide * kPadSide;
inline constexpr int kEdgesPerBlock = kBlockVoxels * 3;

/// Normalised TSDF used in place of an exact 0: half an int16 unit on the outside. A zero
/// counts as outside (the case index tests F < 0), and nudging it keeps every vertex strictly
/// inside its edge, so vertices of different edges never coincide.
inline constexpr float kZeroTsdf = 0.5f / kTsdfScale;

HIVOX_HD inline int pad_index(int x, int y, int z) {
  return (x - kPadLo) + kPadSide * ((y - kPadLo) + kPadSide * (z - kPadLo));
}

/// Index of neighbour block (dx, dy, dz), each in [-1, 1], in `PaddedBlock::neighbour_ptr`.
HIVOX_HD inline int pad_slot(int dx, int dy, int dz) {
  return (dx + 1) + 3 * ((dy + 1) + 3 * (dz + 1));
}

/// How the region of a neighbouring block position, at the meshed block's level, is stored.
enum class Region : uint8_t {
  Same,     ///< a block of this level
  Finer,    ///< a Split entry: finer levels
  Coarser,  ///< inside a block of a coarser level
  None,     ///< nowhere
};

/// A block's voxels with an apron from its neighbours, as the cells and edges read them.
struct PaddedBlock {
  float tsdf[kPadVoxels];             ///< normalised TSDF (0 replaced by kZeroTsdf)
  uint8_t valid[kPadVoxels];          ///< 1: known, with weight >= min_weight
  ColorVoxel color[kPadVoxels];       ///< filled only when colour is gathered
  int32_t neighbour_ptr[27];          ///< pool index of each same-level neighbour, or < 0
  Region neighbour_region[27];        ///< how each neighbour's region is stored
  int8_t neighbour_level[27];         ///< the level of a Coarser neighbour's block
  bool other_levels;                  ///< some neighbour region is stored at another level
  uint8_t cell_valid[kPadVoxels];     ///< 1: a cell of this level with all 8 corners valid
  int8_t touching_level[kPadVoxels];  ///< see mark_coarser_borders
};

/// How block `pos` of `level` is stored (see Region); `ptr` receives its pool index when Same,
/// `coarse_level` the level of the block covering it when Coarser.
HIVOX_HD inline Region region_of(const MapView& map, BlockLookupCache& cache, int level,
                                 const Vec3i& pos, int32_t* ptr, int* coarse_level) {
  *ptr = cache.find(map, level, pos);
  if (*ptr >= 0) return Region::Same;
  if (*ptr == kPtrSplit) return Region::Finer;
  return coarser_holder(map, cache, level, pos, coarse_level) >= 0 ? Region::Coarser : Region::None;
}

/// Fills `b.touching_level` (when some neighbour is Coarser): for each padded point, the
/// coarsest level of a Coarser neighbour whose block, closed (faces, edges and corners
/// included), contains it, or -1.
HIVOX_HD inline void mark_coarser_borders(PaddedBlock& b) {
  // Neighbour s (-1, 0, 1 per axis) covers [8 s, 8 s + 8] closed, clipped to the padded range.
  auto lo = [](int s) { return s < 0 ? kPadLo : 8 * s; };
  auto hi = [](int s) { return s > 0 ? kPadLo + kPadSide - 1 : 8 * s + 8; };
  for (int i = 0; i < kPadVoxels; ++i) b.touching_level[i] = -1;
  for (int sz = -1; sz <= 1; ++sz)
    for (int sy = -1; sy <= 1; ++sy)
      for (int sx = -1; sx <= 1; ++sx) {
        const int slot = pad_slot(sx, sy, sz);
        if (b.neighbour_region[slot] != Region::Coarser) continue;
        const int8_t level = b.neighbour_level[slot];
        for (int z = lo(sz); z <= hi(sz); ++z)
          for (int y = lo(sy); y <= hi(sy); ++y)
            for (int x = lo(sx); x <= hi(sx); ++x) {
              int8_t& t = b.touching_level[pad_index(x, y, z)];
              if (level > t) t = level;
            }
      }
}

/// Fills `out` for the level-`level` block at `pos` stored in pool block `ptr`.
///
/// Voxels of this level's blocks are read as they are. Where the apron reaches into a region
/// stored at another level, points are sampled there: a finer level has a voxel exactly at each
/// point; a coarser one gives its trilinear value on its own lattice. Points on the border of a
/// coarser region (its faces, edges, corners) take the coarse value too, even where they are
/// this level's own voxels: both sides of a level boundary then cut the boundary plane along
/// the same lines, and the surface has no crack there (up to the difference between a coarse
/// face's bilinear zero set and its straight marching-cubes segment). A point is valid when it
/// is known with at least `min_weight` observations. Only cells whose lower corner lies in a
/// block of this level are valid: the others are cells of other levels, meshed there.
HIVOX_HD inline void gather_padded_block(const MapView& map, BlockLookupCache& cache, int level,
                                         const Vec3i& pos, int32_t ptr, float min_weight,
                                         bool with_color, PaddedBlock& out) {
  bool any_coarser = false;
  out.other_levels = false;
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int slot = pad_slot(dx, dy, dz);
        int coarse = -1;
        Region r = Region::Same;
        int32_t nb = ptr;
        if ((dx | dy | dz) != 0)
          r = region_of(map, cache, level, pos + Vec3i{dx, dy, dz}, &nb, &coarse);
        out.neighbour_ptr[slot] = r == Region::Same ? nb : -1;
        out.neighbour_region[slot] = r;
        out.neighbour_level[slot] = static_cast<int8_t>(coarse);
        any_coarser = any_coarser || r == Region::Coarser;
        out.other_levels = out.other_levels || r == Region::Coarser || r == Region::Finer;
      }
  const Vec3i origin{pos.x * kBlockSide, pos.y * kBlockSide, pos.z * kBlockSide};
  if (any_coarser) mark_coarser_borders(out);
  for (int z = kPadLo; z < kPadLo + kPadSide; ++z)
    for (int y = kPadLo; y < kPadLo + kPadSide; ++y)
      for (int x = kPadLo; x < kPadLo + kPadSide; ++x) {
        const int i = pad_index(x, y, z);
        // x >> 3 is -1, 0 or 1 here (floor division); x & 7 the voxel inside that block.
        const int slot = pad_slot(x >> 3, y >> 3, z >> 3);
        const int coarse = any_coarser ? out.touching_level[i] : -1;
        int32_t vptr = out.neighbour_ptr[slot];
        int vindex = voxel_index(x & 7, y & 7, z & 7);
        float f = 1.0f;
        bool ok = false;
        if (coarse >= 0) {
          ok = sample_on_coarser_lattice(map, cache, level, origin + Vec3i{x, y, z}, coarse,
                                         min_weight, &f, &vptr, &vindex);
        } else {
          Vec3i voxel;
          if (vptr < 0 && out.neighbour_region[slot] == Region::Finer &&
              lattice_voxel(map, cache, level, origin + Vec3i{x, y, z}, &vptr, &voxel) >= 0)
            vindex = local_voxel_index(voxel);
          if (vptr >= 0) {
            const TsdfVoxel t = map.tsdf[static_cast<int64_t>(vptr) * kBlockVoxels + vindex];
            f = tsdf_to_float(t.tsdf);
            ok = static_cast<float>(t.weight) >= min_weight;
          }
        }
        if (!ok) {
          out.tsdf[i] = 1.0f;
          out.valid[i] = 0;
          if (with_color) out.color[i] = ColorVoxel{};
          continue;
        }
        out.tsdf[i] = f == 0.0f ? kZeroTsdf : f;
        out.valid[i] = 1;
        if (with_color)
          out.color[i] = map.color[static_cast<int64_t>(vptr) * kBlockVoxels + vindex];
      }
  // A cell is valid when its 8 corners are: AND over x, then y, then z neighbours.
  for (int i = 0; i < kPadVoxels; ++i) out.cell_valid[i] = out.valid[i];
  const int step[3] = {1, kPadSide, kPadSide * kPadSide};
  for (int axis = 0; axis < 3; ++axis)
    for (int z = kPadLo; z < kPadLo + kPadSide - (axis == 2); ++z)
      for (int y = kPadLo; y < kPadLo + kPadSide - (axis == 1); ++y)
        for (int x = kPadLo; x < kPadLo + kPadSide - (axis == 0); ++x) {
          const int i = pad_index(x, y, z);
          out.cell_valid[i] &= out.cell_valid[i + step[axis]];
        }
  if (!out.other_levels) return;
  for (int z = kPadLo; z < kPadLo + kPadSide; ++z)
    for (int y = kPadLo; y < kPadLo + kPadSide; ++y)
      for (int x = kPadLo; x < kPadLo + kPadSide; ++x)
        if (out.neighbour_region[pad_slot(x >> 3, y >> 3, z >> 3)] != Region::Same)
          out.cell_valid[pad_index(x, y, z)] = 0;
}

/// Offset of corner c (numbering of mc_table.h) from the cell's lower corner.
HIVOX_HD inline Vec3i corner_offset(int c) {
  return {c & 1, (c >> 1) & 1, (c >> 2) & 1};
}

/// Case index of the cell with lower corner (x, y, z): bit c set when corner c is inside.
HIVOX_HD inline int cell_case(const PaddedBlock& b, int x, int y, int z) {
  // Corner k's offset is computed, not read from a local table: GCC 12's UBSan misreports
  // loads from such a table in this unrolled loop as out of bounds.
  const int i = pad_index(x, y, z);
  int c = 0;
  for (int k = 0; k < 8; ++k) {
    const int d = (k & 1) + ((k >> 1) & 1) * kPadSide + ((k >> 2) & 1) * kPadSide * kPadSide;
    c |= (b.tsdf[i + d] < 0.0f ? 1 : 0) << k;
  }
  return c;
}

/// Whether owned edge (x, y, z, axis) — all coordinates in [0, 7] — carries a vertex: its ends
/// differ in sign and at least one of the 4 cells around it is valid (then both ends are).
HIVOX_HD inline bool edge_has_vertex(const PaddedBlock& b, int x, int y, int z, int axis) {
  const int step[3] = {1, kPadSide, kPadSide * kPadSide};
  const int i = pad_index(x, y, z);
  if ((b.tsdf[i] < 0.0f) == (b.tsdf[i + step[axis]] < 0.0f)) return false;
  const int u = step[mc::other_axis(axis, 0)], v = step[mc::other_axis(axis, 1)];
  return (b.cell_valid[i] | b.cell_valid[i - u] | b.cell_valid[i - v] | b.cell_valid[i - u - v]) !=
         0;
}

/// TSDF gradient (per voxel) at padded point i: central differences where both neighbours are
/// valid, one-sided where one is, 0 along an axis where none is.
HIVOX_HD inline Vec3f tsdf_gradient(const PaddedBlock& b, int i) {
  const int step[3] = {1, kPadSide, kPadSide * kPadSide};
  Vec3f g;
  for (int k = 0; k < 3; ++k) {
    const int lo = i - step[k], hi = i + step[k];
    if (b.valid[lo] && b.valid[hi])
      g[k] = 0.5f * (b.tsdf[hi] - b.tsdf[lo]);
    else if (b.valid[hi])
      g[k] = b.tsdf[hi] - b.tsdf[i];
    else if (b.valid[lo])
      g[k] = b.tsdf[i] - b.tsdf[lo];
    else
      g[k] = 0.0f;
  }
  return g;
}

HIVOX_HD inline uint8_t lerp_channel(uint8_t a, uint8_t b, float t) {
  return static_cast<uint8_t>(static_cast<float>(a) + (static_cast<float>(b) - a) * t + 0.5f);
}

/// Colour of an edge vertex: linear between the ends; an end without colour observations is
/// ignored, and mid-grey stands in when neither has any.
HIVOX_HD inline Rgb8 edge_color(const ColorVoxel& a, const ColorVoxel& b, float t) {
  if (a.weight > 0 && b.weight > 0)
    return {lerp_channel(a.r, b.r, t), lerp_channel(a.g, b.g, t), lerp_channel(a.b, b.b, t)};
  if (a.weight > 0) return {a.r, a.g, a.b};
  if (b.weight > 0) return {b.r, b.g, b.b};
  return {128, 128, 128};
}

struct EdgeVertex {
  Vec3f position_w;
  Vec3f normal_w;
  Rgb8 color;
};

/// The vertex on owned edge (x, y, z, axis) of the block at `block_pos` (voxel size
/// `voxel_size_m`), assuming `edge_has_vertex`. Position by linear interpolation of the TSDF;
/// normal from the gradients at the two ends, interpolated the same way and normalised (it
/// points to increasing TSDF, i.e. free space; along the edge towards the outside end when the
/// gradient vanishes).
HIVOX_HD inline EdgeVertex edge_vertex(const PaddedBlock& b, const Vec3i& block_pos,
                                       float voxel_size_m, int x, int y, int z, int axis,
                                       bool with_normal, bool with_color) {
  const int step[3] = {1, kPadSide, kPadSide * kPadSide};
  const int i0 = pad_index(x, y, z), i1 = i0 + step[axis];
  const float f0 = b.tsdf[i0], f1 = b.tsdf[i1];
  const float t = f0 / (f0 - f1);  // f0 and f1 differ in sign and neither is 0
  EdgeVertex v;
  Vec3f p{static_cast<float>(block_pos.x * kBlockSide + x),
          static_cast<float>(block_pos.y * kBlockSide + y),
          static_cast<float>(block_pos.z * kBlockSide + z)};
  p[axis] += t;
  v.position_w = p * voxel_size_m;
  if (with_normal) {
    const Vec3f g0 = tsdf_gradient(b, i0), g1 = tsdf_gradient(b, i1);
    Vec3f n = normalized(g0 * (1.0f - t) + g1 * t);
    if (n.x == 0.0f && n.y == 0.0f && n.z == 0.0f) n[axis] = f1 > f0 ? 1.0f : -1.0f;
    v.normal_w = n;
  }
  if (with_color) v.color = edge_color(b.color[i0], b.color[i1], t);
  return v;
}

/// A triangle corner before global vertex indices exist: the vertex on edge `edge` (local edge
/// id) of block `block` (index in the sorted block list). When the vertex belongs to the block
/// that made the triangle, it is resolved at once and `edge` holds kResolvedEdge | its rank
/// there.
struct EdgeRef {
  int32_t block;
  uint16_t edge;
};
inline constexpr uint16_t kResolvedEdge = 0x8000;

/// Edge ids over the padded block (pad_index * 3 + axis), for edges owned by no block.
inline constexpr int kPadEdges = kPadVoxels * 3;
static_assert(kEdgesPerBlock + kPadEdges < kResolvedEdge);

/// What marching cubes over one block needs besides its look-up cache.
struct MeshBlockScratch {
  PaddedBlock padded;
  int16_t rank[kEdgesPerBlock];      ///< own edge id -> its vertex's rank in the block, or -1
  int16_t boundary_rank[kPadEdges];  ///< padded edge id -> its vertex's rank in the block
};

/// What a block's marching cubes read besides the map.
struct MeshBlockInput {
  BlockRef block;
  int32_t self = 0;                       ///< the block's index in the sorted block list
  const int32_t* index_of_ptr = nullptr;  ///< pool index -> index in the sorted block list
  int min_weight = 1;
  bool normals = true, color = false;
  bool cells = true;  ///< false: the vertices on its owned edges only (no triangles)
  /// The marching-cubes cases: &mc::kMcTable on the host, a copy in device memory on a GPU
  /// (device code cannot index a host constexpr array).
  const mc::McTable* table = nullptr;
};

/// Marching cubes over one block, written once for every driver: `emit` receives the vertices
/// on the edges the block owns, in ascending local edge id (`owned_vertex(edge, vertex)`; ranks
/// 0, 1, ...), then, mixed with the triangles' corners (`corner(EdgeRef)`, three a triangle),
/// the vertices on level-boundary edges that no block of its level owns (`boundary_vertex`,
/// ranks following; every block whose cells use such an edge makes the same vertex, and the
/// copies are merged afterwards). `Emit::kVertices` false: the vertices are not computed (a
/// counting pass).
template <typename Emit>
HIVOX_HD void mesh_block(const MapView& view, BlockLookupCache& cache, const MeshBlockInput& in,
                         MeshBlockScratch& scratch, Emit& emit) {
  const BlockRef& b = in.block;
  PaddedBlock& pb = scratch.padded;
  gather_padded_block(view, cache, b.level, b.pos, b.ptr, in.min_weight, in.color, pb);
  if (pb.other_levels)
    for (int i = 0; i < kPadEdges; ++i) scratch.boundary_rank[i] = -1;
  for (int i = 0; i < kEdgesPerBlock; ++i) scratch.rank[i] = -1;
  const float voxel_m = view.level[b.level].voxel_size_m;
  auto vertex = [&](int x, int y, int z, int axis) {
    return Emit::kVertices ? edge_vertex(pb, b.pos, voxel_m, x, y, z, axis, in.normals, in.color)
                           : EdgeVertex{};
  };
  int16_t vertices = 0;
  for (int z = 0; z < kBlockSide; ++z)
    for (int y = 0; y < kBlockSide; ++y)
      for (int x = 0; x < kBlockSide; ++x)
        for (int axis = 0; axis < 3; ++axis) {
          if (!edge_has_vertex(pb, x, y, z, axis)) continue;
          const int id = voxel_index(x, y, z) * 3 + axis;
          scratch.rank[id] = vertices++;
          emit.owned_vertex(static_cast<uint16_t>(id), vertex(x, y, z, axis));
        }
  if (!in.cells) return;
  for (int z = 0; z < kBlockSide; ++z)
    for (int y = 0; y < kBlockSide; ++y)
      for (int x = 0; x < kBlockSide; ++x) {
        if (!pb.cell_valid[pad_index(x, y, z)]) continue;
        const int c = cell_case(pb, x, y, z);
        if (c == 0 || c == 255) continue;
        const mc::McCase& mcase = in.table->cases[c];
        for (int t = 0; t < mcase.triangle_count; ++t)
          for (int k = 0; k < 3; ++k) {
            const int e = mcase.triangles[t][k];
            const Vec3i p = Vec3i{x, y, z} + corner_offset(mc::mc_edge_corner(e, 0));
            const int axis = mc::mc_edge_axis(e);
            const int id = voxel_index(p.x & 7, p.y & 7, p.z & 7) * 3 + axis;
            if (((p.x | p.y | p.z) >> 3) == 0) {
              emit.corner({in.self, static_cast<uint16_t>(kResolvedEdge | scratch.rank[id])});
            } else if (const int32_t nb = pb.neighbour_ptr[pad_slot(p.x >> 3, p.y >> 3, p.z >> 3)];
                       nb >= 0) {
              // The edge starts in a +x/+y/+z neighbour of this level, which owns it.
              emit.corner({in.index_of_ptr[nb], static_cast<uint16_t>(id)});
            } else {
              // The edge starts in a region stored at another level: no block of this level
              // owns it, so every block whose cells use it makes the vertex (the same one:
              // same samples, same arithmetic).
              int16_t& r = scratch.boundary_rank[pad_index(p.x, p.y, p.z) * 3 + axis];
              if (r < 0) {
                r = vertices++;
                emit.boundary_vertex(vertex(p.x, p.y, p.z, axis));
              }
              emit.corner({in.self, static_cast<uint16_t>(kResolvedEdge | r)});
            }
          }
      }
}

}  // namespace hivox::kernels

#pragma once
// Meshing in passes over a block list, for a driver that cannot grow a vector per block (the
// CUDA mesher): count each block's vertices and triangle corners, lay the blocks' outputs out
// one after another (exclusive sums, mesh_layout), write each block's vertices and corners at
// its offsets, then turn every corner into a vertex index. The per-block and per-corner steps
// are written here once; tests run them on the host and get extract_mesh's mesh exactly.

#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

#include "hivox/core/hd.h"
#include "hivox/mesh/extract_mesh.h"
#include "mesh/mesh_kernels.h"

namespace hivox::kernels {

/// What marching cubes over one block makes.
struct BlockMeshCount {
  int32_t owned = 0;     ///< vertices on edges the block owns: ranks [0, owned)
  int32_t vertices = 0;  ///< all its vertices, the owned ones first
  int32_t corners = 0;   ///< triangle corners, three a triangle
};

/// The counting pass's emitter: no vertex is computed.
struct CountEmitter {
  static constexpr bool kVertices = false;
  BlockMeshCount n;
  HIVOX_HD void owned_vertex(uint16_t, const EdgeVertex&) {
    ++n.owned;
    ++n.vertices;
  }
  HIVOX_HD void boundary_vertex(const EdgeVertex&) { ++n.vertices; }
  HIVOX_HD void corner(const EdgeRef&) { ++n.corners; }
};

/// A mesh's arrays, the blocks' parts one after another. `normals_w` and `colors` may be null.
struct MeshArrays {
  Vec3f* positions_w = nullptr;
  Vec3f* normals_w = nullptr;
  Rgb8* colors = nullptr;
  uint8_t* levels = nullptr;
  uint16_t* edges = nullptr;  ///< per owned vertex: its edge's local id in its block
  EdgeRef* corners = nullptr;
};

/// The writing pass's emitter: a block's vertices and corners from its offsets on.
struct WriteEmitter {
  static constexpr bool kVertices = true;
  MeshArrays out;
  int64_t next_vertex = 0;
  int64_t next_corner = 0;
  uint8_t level = 0;

  HIVOX_HD void owned_vertex(uint16_t edge, const EdgeVertex& v) {
    out.edges[next_vertex] = edge;
    boundary_vertex(v);
  }
  HIVOX_HD void boundary_vertex(const EdgeVertex& v) {
    const int64_t i = next_vertex++;
    out.positions_w[i] = v.position_w;
    if (out.normals_w != nullptr) out.normals_w[i] = v.normal_w;
    if (out.colors != nullptr) out.colors[i] = v.color;
    out.levels[i] = level;
  }
  HIVOX_HD void corner(const EdgeRef& r) { out.corners[next_corner++] = r; }
};

/// What the passes read besides the map. The offsets and counts are read from the writing pass
/// on.
struct MeshPassInput {
  const BlockRef* blocks = nullptr;       ///< in key order (plan_mesh_blocks)
  const int32_t* index_of_ptr = nullptr;  ///< pool index -> index in `blocks`
  const uint8_t* cells = nullptr;         ///< per block, 0: its owned vertices only
  int32_t block_count = 0;
  int min_weight = 1;
  bool normals = true, color = false;
  const mc::McTable* table = nullptr;
  const BlockMeshCount* counts = nullptr;
  const int64_t* vertex_offset = nullptr;  ///< first vertex of each block
  const int64_t* corner_offset = nullptr;  ///< first corner of each block
};

HIVOX_HD inline MeshBlockInput mesh_block_input(const MeshPassInput& p, int32_t i) {
  MeshBlockInput in;
  in.block = p.blocks[i];
  in.self = i;
  in.index_of_ptr = p.index_of_ptr;
  in.min_weight = p.min_weight;
  in.normals = p.normals;
  in.color = p.color;
  in.cells = p.cells[i] != 0;
  in.table = p.table;
  return in;
}

/// Pass one, for block i.
HIVOX_HD inline BlockMeshCount count_block_mesh(const MapView& view, BlockLookupCache& cache,
                                                const MeshPassInput& p, int32_t i,
                                                MeshBlockScratch& scratch) {
  CountEmitter emit;
  mesh_block(view, cache, mesh_block_input(p, i), scratch, emit);
  return emit.n;
}

/// Pass two, for block i: its vertices and corners into `out` at its offsets.
HIVOX_HD inline void write_block_mesh(const MapView& view, BlockLookupCache& cache,
                                      const MeshPassInput& p, int32_t i, MeshBlockScratch& scratch,
                                      const MeshArrays& out) {
  WriteEmitter emit;
  emit.out = out;
  emit.next_vertex = p.vertex_offset[i];
  emit.next_corner = p.corner_offset[i];
  emit.level = static_cast<uint8_t>(p.blocks[i].level);
  mesh_block(view, cache, mesh_block_input(p, i), scratch, emit);
}

/// The rank of `edge` among a block's owned edges (`edges`, `count` of them, ascending), or -1.
HIVOX_HD inline int32_t owned_rank(const uint16_t* edges, int32_t count, uint16_t edge) {
  int32_t lo = 0, hi = count;
  while (lo < hi) {
    const int32_t mid = (lo + hi) / 2;
    if (edges[mid] < edge)
      lo = mid + 1;
    else
      hi = mid;
  }
  return lo < count && edges[lo] == edge ? lo : -1;
}

/// Pass three, for one corner: its vertex's index, or -1 when its owner made no vertex on that
/// edge (a bug: the owner decides from the same voxels as the cell that uses the edge).
HIVOX_HD inline int64_t resolve_corner(const MeshPassInput& p, const uint16_t* edges,
                                       const EdgeRef& r) {
  const int64_t base = p.vertex_offset[r.block];
  if ((r.edge & kResolvedEdge) != 0) return base + (r.edge & ~kResolvedEdge);
  const int32_t rank = owned_rank(edges + base, p.counts[r.block].owned, r.edge);
  return rank < 0 ? -1 : base + rank;
}

}  // namespace hivox::kernels

namespace hivox::detail {

/// The blocks a mesh is made of and what the passes read of them.
struct MeshBlocks {
  std::vector<BlockRef> blocks;  ///< in key order (level, z, y, x): pool positions do not matter
  std::vector<uint8_t> cells;    ///< per block, 1: its cells; 0: the vertices on its edges only
  std::vector<int32_t> index_of_ptr;  ///< pool index -> index in `blocks`, or -1
};

/// Plans the mesh of the `allocated` blocks (pool indices below `high_water`): all of them in
/// key order, or with `bounds` those whose cells, reaching a voxel into the next block, meet the
/// box, and the +x/+y/+z neighbours whose edges those cells use (vertices only). `ptr_of(level,
/// pos)`: the pool index of a block of that level, or < 0; when empty, a binary search in the
/// sorted list (for a driver without the map's hash tables at hand).
MeshBlocks plan_mesh_blocks(std::vector<BlockRef> allocated, int32_t high_water,
                            const MapParams& params, const std::optional<Box3f>& bounds,
                            const std::function<int32_t(int, const Vec3i&)>& ptr_of = {});

/// The passes' input for `params` over `plan`'s blocks (host pointers into `plan`, the host's
/// marching-cubes table; a device driver points them at its copies). `map_color`: the map
/// stores colour.
kernels::MeshPassInput mesh_pass_input(const MeshParams& params, bool map_color,
                                       const MeshBlocks& plan);

/// Where each block's vertices and corners start (exclusive sums of `counts`, one more entry
/// than blocks: the totals last). Throws `Error(OutOfCapacity)` past the int32 vertex indices.
struct MeshLayout {
  std::vector<int64_t> vertex_offset, corner_offset;
  int64_t vertices() const { return vertex_offset.back(); }
  int64_t corners() const { return corner_offset.back(); }
};
MeshLayout mesh_layout(const kernels::BlockMeshCount* counts, int64_t blocks);

/// Merges the vertices listed in `candidates` that sit at exactly the same position (copies of
/// one vertex made by several blocks) into the first copy, and compacts the mesh.
void merge_vertex_copies(std::vector<int32_t>& candidates, TriangleMesh& mesh);

/// The vertices on level-boundary edges (after each block's owned ones), which several blocks
/// make, merged (merge_vertex_copies).
void merge_boundary_vertices(const kernels::BlockMeshCount* counts, const MeshLayout& layout,
                             TriangleMesh& mesh);

/// extract_mesh's last steps on a whole map's mesh: cropped to `params.bounds`, small pieces
/// removed (`join_distance_m`: the finest voxel); `removed` (optional) receives what went.
TriangleMesh finish_mesh(TriangleMesh mesh, const MeshParams& params, float join_distance_m,
                         RemovedPieces* removed);

}  // namespace hivox::detail

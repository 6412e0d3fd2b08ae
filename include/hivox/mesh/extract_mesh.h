#pragma once
/// @file
/// Marching cubes over the voxel block map (DESIGN §7).

#include <cstdint>

#include "hivox/map/voxel_block_map.h"
#include "hivox/mesh/params.h"
#include "hivox/mesh/triangle_mesh.h"

namespace hivox {

/// Extracts the zero level set of the TSDF as a triangle mesh.
///
/// Every allocated block is meshed at its own level: its cells are its 8x8x8 voxels taken as
/// lower corners, reaching into the +x/+y/+z neighbour blocks of the same level. A cell is
/// skipped when one of its corners lies in a block missing at that level or has a weight below
/// `params.min_weight`. Case tables come from a face-consistent rule (see src/mesh/mc_table.h),
/// so neighbouring cells agree on every shared face and a fully observed closed surface gives a
/// closed 2-manifold mesh.
///
/// Vertices are shared: each grid edge (its lower voxel, axis and level) yields at most one
/// vertex, also across block borders, and every vertex is used by a triangle. Positions come
/// from linear interpolation of the TSDF along the edge; normals (if `compute_normals`) from
/// the TSDF gradient, pointing to free space; colours (if `with_color` and the map stores
/// colour) interpolated from the voxel colours; `levels` holds each vertex's level. Triangles
/// are counter-clockwise seen from free space.
///
/// Multi-level maps: every block is meshed at its own level, and its cells reach across level
/// boundaries: a corner in a finer region reads the finer voxel at that point, one in a coarser
/// region the coarse level's trilinear value there. Points on the border of a coarser region
/// take the coarse value even on the finer side, so both sides cut the boundary plane along the
/// same lines and the surfaces meet without a crack (they differ only by how far a coarse
/// face's bilinear zero set bends away from its straight marching-cubes segment: a few hundredths
/// of a voxel on an exact sphere, ~0.2 fine voxel on fused data). Vertices on both sides of a
/// boundary are not merged (T-junctions), so such a mesh is closed geometrically, not
/// topologically; the vertices on a level's boundary edges, which several of its blocks make,
/// are merged.
///
/// Runs in parallel over blocks; the output (order included) depends only on the map's content,
/// not on the thread count or on where blocks sit in the pool. Throws `Error(InvalidArgument)`
/// for bad `params`.
/// What `MeshParams::min_piece_triangles` removed.
struct RemovedPieces {
  int64_t pieces = 0;
  int64_t triangles = 0;
};
/// `removed` (optional) receives what the small-piece removal took away.
TriangleMesh extract_mesh(const VoxelBlockMap& map, const MeshParams& params = {},
                          RemovedPieces* removed = nullptr);

}  // namespace hivox

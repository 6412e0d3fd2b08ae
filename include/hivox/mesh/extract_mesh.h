#pragma once
/// @file
/// Marching cubes over the voxel block map (DESIGN §7).

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
/// Multi-level maps: cells that would need voxels of a neighbouring block stored at another
/// level are skipped, so the surface has a gap of up to one cell along level boundaries.
///
/// Runs in parallel over blocks; the output (order included) depends only on the map's content,
/// not on the thread count or on where blocks sit in the pool. Throws `Error(InvalidArgument)`
/// for bad `params`.
TriangleMesh extract_mesh(const VoxelBlockMap& map, const MeshParams& params = {});

}  // namespace hivox

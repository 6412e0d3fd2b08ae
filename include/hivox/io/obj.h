#pragma once
/// @file
/// Wavefront OBJ meshes, for tools that read OBJ rather than PLY, and reference meshes given as
/// OBJ.

#include <filesystem>

#include "hivox/mesh/triangle_mesh.h"

namespace hivox {

/// Writes `mesh` as text OBJ: `v x y z` (followed by `r g b` in [0, 1] when the mesh has
/// colours, the common extension MeshLab, Open3D and Blender read), `vn` normals when it has
/// them, and faces `f a//a b//b c//c` (1-based; `f a b c` without normals). Written atomically.
/// An inconsistent mesh is `Error(InvalidArgument)`, an unwritable file `Error(Io)`.
void write_obj(const std::filesystem::path& path, const TriangleMesh& mesh);

/// Reads a text OBJ mesh: `v x y z` (with `r g b` in [0, 1] after them on every vertex: colours),
/// faces `f` of 3 or more corners (`a`, `a/t`, `a//n`, `a/t/n`; 1-based or negative from the
/// last vertex; polygons split into a fan). Other lines (normals, texture coordinates, groups,
/// materials) are skipped. A missing file is `Error(Io)`; a malformed number, a face with fewer
/// than 3 corners or an index out of range is `Error(InvalidData)` naming `FILE:LINE`.
TriangleMesh read_obj(const std::filesystem::path& path);

}  // namespace hivox

#pragma once
/// @file
/// Wavefront OBJ meshes, for tools that read OBJ rather than PLY.

#include <filesystem>

#include "hivox/mesh/triangle_mesh.h"

namespace hivox {

/// Writes `mesh` as text OBJ: `v x y z` (followed by `r g b` in [0, 1] when the mesh has
/// colours, the common extension MeshLab, Open3D and Blender read), `vn` normals when it has
/// them, and faces `f a//a b//b c//c` (1-based; `f a b c` without normals). Written atomically.
/// An inconsistent mesh is `Error(InvalidArgument)`, an unwritable file `Error(Io)`.
void write_obj(const std::filesystem::path& path, const TriangleMesh& mesh);

}  // namespace hivox

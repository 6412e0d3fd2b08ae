#pragma once
/// @file
/// PLY triangle meshes. Written as binary little-endian; read from binary (either byte order)
/// or ASCII files. Every failure is an `Error` whose message names the file and the problem.

#include <filesystem>

#include "hivox/mesh/triangle_mesh.h"

namespace hivox {

/// Writes `mesh` as binary little-endian PLY: vertex `x y z` (float), `nx ny nz` (float) when
/// the mesh has normals, `red green blue` (uchar) when it has colours, `level` (uchar) when it
/// has levels; faces as `list uchar int vertex_indices`. An inconsistent mesh is
/// `Error(InvalidArgument)`, an unwritable file `Error(Io)`.
void write_ply(const std::filesystem::path& path, const TriangleMesh& mesh);

/// Reads a PLY mesh (ascii, binary_little_endian or binary_big_endian). Vertex `x y z` are
/// required; `nx ny nz`, `red green blue` (uchar, or float in [0, 1]) and `level` are read when
/// all present; other properties (any type, lists included) and other elements are skipped.
/// Faces (`vertex_indices` or `vertex_index`) with more than 3 corners are split into a
/// triangle fan. A missing file is `Error(Io)`; a malformed header or body, a face with fewer
/// than 3 corners or an index out of range is `Error(InvalidData)`.
TriangleMesh read_ply(const std::filesystem::path& path);

}  // namespace hivox

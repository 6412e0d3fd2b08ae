#pragma once
/// @file
/// OFF (Object File Format) meshes, as used for the ground-truth shapes in shared/data/meshes.

#include <filesystem>

#include "hivox/mesh/triangle_mesh.h"

namespace hivox {

/// Reads an ASCII OFF file: header `OFF` (also `COFF`, `NOFF`, `CNOFF` with per-vertex normals
/// and/or colours), then `vertices faces edges`, one vertex and one face per line; `#` starts
/// a comment. Polygons are split into triangle fans. A missing file is `Error(Io)`, malformed
/// content `Error(InvalidData)` naming the file and line, binary OFF `Error(Unsupported)`.
TriangleMesh read_off(const std::filesystem::path& path);

}  // namespace hivox

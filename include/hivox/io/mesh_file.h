#pragma once
/// @file
/// Reading a mesh file whatever its format, by its extension: `.ply`, `.obj` or `.off`.

#include <filesystem>

#include "hivox/mesh/triangle_mesh.h"

namespace hivox {

/// read_ply, read_obj or read_off by the extension (any case); another extension is
/// `Error(Unsupported)` naming the file and the formats.
TriangleMesh read_mesh(const std::filesystem::path& path);

}  // namespace hivox

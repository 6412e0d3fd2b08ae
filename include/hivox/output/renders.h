#pragma once
/// @file
/// A raycast's pictures as PNG files (the renders a run writes).

#include <filesystem>
#include <string>
#include <vector>

#include "hivox/raycast/raycaster.h"

namespace hivox {

/// Writes the renders of raycast `r` into `dir`: `{prefix}depth.png` (colour-mapped depth),
/// `normals.png`, `shaded.png`, `color.png` and `levels.png` (the refinement level of each
/// surface point). Returns the files written; throws `Error(Io)` naming a file it cannot write.
std::vector<std::filesystem::path> write_renders(const RaycastResult& r,
                                                 const std::filesystem::path& dir,
                                                 const std::string& prefix = "");

}  // namespace hivox

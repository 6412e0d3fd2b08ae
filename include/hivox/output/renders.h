#pragma once
/// @file
/// A raycast's pictures as PNG files (the renders a run writes).

#include <filesystem>
#include <string>
#include <vector>

#include "hivox/map/params.h"
#include "hivox/raycast/raycaster.h"

namespace hivox {

/// Writes the renders of raycast `r` of a map shaped by `map` into `dir`: `{prefix}depth.png`
/// (colour-mapped depth, with a scale bar below giving the depths of the ramp's ends),
/// `normals.png`, `shaded.png`, `color.png` and `levels.png` (the refinement level of each
/// surface point, with a legend below: each level's colour and voxel size). Returns the files
/// written; throws `Error(Io)` naming a file it cannot write.
std::vector<std::filesystem::path> write_renders(const RaycastResult& r, const MapParams& map,
                                                 const std::filesystem::path& dir,
                                                 const std::string& prefix = "");

}  // namespace hivox

#pragma once
/// @file
/// A map exported for analysis as numpy's `.npz` (a zip of `.npy` arrays, `numpy.load` reads it).

#include <filesystem>

#include "hivox/map/voxel_block_map.h"

namespace hivox {

/// Writes the map's voxels as a `.npz` file. Arrays, for each level `l` (blocks in the canonical
/// order of map files, sorted by z, y, x):
/// - `level<l>_coords`: int32 (N, 3), block coordinates (x, y, z); voxel (i, j, k) of a block
///   sits at world position (8 * coords + (i, j, k)) * voxel_size_m[l];
/// - `level<l>_tsdf`: float32 (N, 8, 8, 8) indexed [block, z, y, x], the signed distance in
///   metres (positive in front of surfaces, +truncation_m where unobserved);
/// - `level<l>_weight`: uint16 (N, 8, 8, 8), observations (0 = unobserved);
/// - `level<l>_color`: uint8 (N, 8, 8, 8, 3), sRGB, when the map stores colour;
/// and `voxel_size_m` float32 (levels,), `truncation_m` float32 (). Stored uncompressed (fast;
/// zip it if space matters). Written atomically; an unwritable file is `Error(Io)`.
void write_map_npz(const std::filesystem::path& path, const VoxelBlockMap& map);

}  // namespace hivox

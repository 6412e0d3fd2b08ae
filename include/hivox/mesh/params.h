#pragma once
/// @file
/// Mesh extraction parameters.

#include <cstdint>
#include <optional>
#include <string>

#include "hivox/mesh/triangle_mesh.h"

namespace hivox {

struct MeshParams {
  /// A voxel takes part in meshing only when its weight (number of fused observations, capped
  /// by FusionParams::max_weight) is at least this; a cell is meshed only when all 8 corners
  /// do. Must be >= 1: weight 0 means unobserved, and an unobserved voxel never makes surface.
  /// The default 1 keeps everything observed, so a single frame gives a mesh (Open3D's and
  /// InfiniTAM's behaviour with noise-free or few frames); raise it (e.g. 3) to drop surface
  /// seen only in passing on noisy sequences.
  float min_weight = 1.0f;
  bool compute_normals = true;  ///< per-vertex normals from the TSDF gradient
  bool with_color = true;       ///< per-vertex colour when the map stores colour
  /// Mesh only this box: blocks outside it are skipped and only triangles whose corners all lie
  /// inside are kept.
  std::optional<Box3f> bounds;
  /// Remove connected pieces of fewer triangles than this (0: keep all); pieces are joined
  /// across level boundaries (remove_small_pieces, joined within a finest voxel).
  int64_t min_piece_triangles = 0;

  /// Throws `Error(InvalidArgument)` naming the bad field.
  void validate() const;
  std::string to_string() const;
};

}  // namespace hivox

#pragma once
/// @file
/// Depth fusion parameters.

#include <string>

namespace hivox {

struct MapParams;

struct FusionParams {
  float truncation_m = 0.024f;  ///< truncation band mu (one metric value for all levels)
  int max_weight = 100;         ///< cap of the per-voxel observation count
  float min_depth_m = 0.2f;     ///< depth below this is ignored
  float max_depth_m = 3.0f;     ///< depth beyond this is ignored
  bool integrate_color = true;  ///< fuse colour when the frame has it and the map stores it

  /// Throws `Error(InvalidArgument)` naming the bad field.
  void validate() const;
  /// Warns (log) about combinations that work badly with `map`, e.g. a truncation band
  /// narrower than two voxels of the coarsest level (holes in coarse surfaces).
  void check_against(const MapParams& map) const;
  std::string to_string() const;
};

}  // namespace hivox

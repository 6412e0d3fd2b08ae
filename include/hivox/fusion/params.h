#pragma once
/// @file
/// Depth fusion parameters.

#include <string>
#include <string_view>

namespace hivox {

struct MapParams;

/// How a voxel reads the depth image where it projects.
enum class DepthSampling {
  /// The nearest pixel (KinectFusion, InfiniTAM, Open3D). On surfaces seen at an angle the depth
  /// steps from pixel to pixel, and the fused TSDF keeps a staircase of those steps, which the
  /// refinement criterion reads as surface detail.
  Nearest,
  /// Bilinear between the 4 pixels around the projection where they are valid and lie within
  /// the truncation band of each other (the nearest pixel across depth edges and next to invalid
  /// pixels). Removes the staircase (noise-free planes: ~6x lower error) at ~1.2x the
  /// integration time.
  Bilinear,
};
std::string_view to_string(DepthSampling sampling);
/// Parses "nearest" or "bilinear"; throws `Error(InvalidArgument)` otherwise.
DepthSampling parse_depth_sampling(std::string_view name);

struct FusionParams {
  float truncation_m = 0.024f;  ///< truncation band mu (one metric value for all levels)
  int max_weight = 100;         ///< cap of the per-voxel observation count
  float min_depth_m = 0.2f;     ///< depth below this is ignored
  float max_depth_m = 3.0f;     ///< depth beyond this is ignored
  bool integrate_color = true;  ///< fuse colour when the frame has it and the map stores it
  DepthSampling depth_sampling = DepthSampling::Bilinear;

  /// Throws `Error(InvalidArgument)` naming the bad field.
  void validate() const;
  /// Warns (log) about combinations that work badly with `map`, e.g. a truncation band
  /// narrower than two voxels of the coarsest level (holes in coarse surfaces).
  void check_against(const MapParams& map) const;
  std::string to_string() const;
};

}  // namespace hivox

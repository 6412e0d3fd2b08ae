#pragma once
/// @file
/// Depth fusion parameters.

#include <string>
#include <string_view>

#include "hivox/core/camera_rig.h"

namespace hivox {

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

/// How frames are fused. The truncation band is the map's (MapParams::truncation_m): its voxels
/// store distances in units of it.
struct FusionParams {
  int max_weight = 100;  ///< cap of the per-voxel observation count
  /// Depths outside this range are ignored. A reconstruction tracks and raycasts over the same
  /// range (Reconstruction passes it on; it has no other copy).
  DepthRange depth_range;
  bool integrate_color = true;  ///< fuse colour when the frame has it and the map stores it
  DepthSampling depth_sampling = DepthSampling::Bilinear;

  /// Throws `Error(InvalidArgument)` naming the bad field.
  void validate() const;
  std::string to_string() const;
};

}  // namespace hivox

#pragma once
/// @file
/// The sensor as the stages see it (`CameraRig`: the depth and colour cameras, where the colour
/// camera sits relative to the depth camera, the raw depth units and the depth noise) and the
/// range of depths a reconstruction uses (`DepthRange`).

#include <string>

#include "hivox/core/camera.h"
#include "hivox/core/pose.h"
#include "hivox/core/sensor_noise.h"

namespace hivox {

/// Colour pixel (u, v) sees what depth pixel (u, v) sees: one camera, no offset between the two.
inline bool color_registered(const PinholeCamera& color_camera, const PinholeCamera& depth_camera,
                             const Pose& T_color_depth) {
  return color_camera == depth_camera && T_color_depth.isApprox(Pose::Identity());
}

struct CameraRig {
  PinholeCamera depth_camera;
  /// Colour camera; equal to `depth_camera` when depth is registered to colour.
  PinholeCamera color_camera;
  /// Maps depth-camera points into the colour-camera frame (identity when registered).
  Pose T_color_depth = Pose::Identity();
  /// Raw depth units per metre (value / depth_scale = metres); 0 when depth is metric already.
  double depth_scale = 0;
  /// Axial depth noise: Kinect-class for recorded data, none for noise-free synthetic depth.
  /// The refinement compares surface detail with it (RefineParams::noise overrides it).
  SensorNoise depth_noise = SensorNoise::kinect();

  /// A rig of one camera seeing depth and colour (registered), metric depth.
  static CameraRig registered(const PinholeCamera& camera);

  /// Colour pixel (u, v) sees what depth pixel (u, v) sees (the free `color_registered`).
  bool color_registered() const {
    return hivox::color_registered(color_camera, depth_camera, T_color_depth);
  }
  /// Throws `Error(InvalidArgument)` naming the bad part (the depth camera, the depth scale, the
  /// colour camera's pose); `what` prefixes the message.
  void validate(const std::string& what = "camera rig") const;
};

/// The depths a reconstruction takes from its depth images, metres along the optical axis: nearer
/// or farther ones are ignored by fusion and tracking, and the model is raycast over the same
/// range.
struct DepthRange {
  float min_m = 0.2f;
  float max_m = 3.0f;

  HIVOX_HD bool contains(float z_m) const { return z_m >= min_m && z_m <= max_m; }
  /// Throws `Error(InvalidArgument)` unless 0 <= min_m < max_m, both finite; `what` names the
  /// range's owner in the message.
  void validate(const std::string& what = "depth range") const;
  std::string to_string() const;
};

}  // namespace hivox

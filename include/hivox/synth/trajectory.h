#pragma once
/// @file
/// Smooth, closed camera paths for synthetic sequences. A path is a function of the phase
/// `s` in [0, 1) over the whole sequence (frame i of N has s = i / N), so every sequence length
/// covers the whole path and the last frame flows smoothly back into the first.
///
/// Camera position in spherical coordinates about the (slightly wobbling) target, z up:
///   azimuth   a(s) = azimuth_rad + (Orbit ? 2 pi s : sweep_rad * sin(2 pi s))
///   elevation e(s) = elevation_rad + elevation_swing_rad * sin(2 pi k s), k = 1 for an Orbit,
///                    2 for an Arc
///   distance  d(s) = distance_m * (1 + distance_swing * sin(4 pi s))
///   eye(s)  = target(s) + d(s) * (cos e cos a, cos e sin a, sin e)
///   target(s) = target_w + target_wobble_m * (sin 4 pi s, sin 6 pi s, 0.5 sin 2 pi s)
/// The camera looks at target(s) with image up along +z (OpenCV axes: its -y points up).

#include <cstddef>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "hivox/core/pose.h"

namespace hivox {

enum class PathKind {
  Arc,    ///< swings left and right in front of the target (indoor scenes)
  Orbit,  ///< one full turn around the target with elevation change (closed objects)
};

struct CameraPath {
  PathKind kind = PathKind::Orbit;
  Eigen::Vector3d target_w = Eigen::Vector3d::Zero();  ///< point the camera looks at
  double distance_m = 0.8;                             ///< mean camera-target distance
  double azimuth_rad = -1.5707963;   ///< Arc: centre azimuth; Orbit: start (about +z from +x)
  double sweep_rad = 0.55;           ///< Arc: azimuth amplitude (+-); unused by an Orbit
  double elevation_rad = 0.2;        ///< mean elevation above the target's horizontal plane
  double elevation_swing_rad = 0.7;  ///< elevation amplitude (+-)
  double distance_swing = 0.05;      ///< relative distance amplitude (+-)
  double target_wobble_m = 0.0;      ///< amplitude of the target's own motion

  /// Throws `Error(InvalidArgument)` naming the bad field.
  void validate() const;
  std::string to_string() const;
};

/// Camera-to-world pose at phase `s` (any real; the path has period 1).
Pose camera_pose(const CameraPath& path, double s);

/// `frames` poses at phases i / frames, time-stamped i / fps seconds (30 Hz by default).
std::vector<StampedPose> make_trajectory(const CameraPath& path, std::size_t frames,
                                         double fps = 30.0);

}  // namespace hivox

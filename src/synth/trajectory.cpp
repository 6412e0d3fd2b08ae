#include "hivox/synth/trajectory.h"

#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "hivox/core/error.h"

namespace hivox {

namespace {}

void CameraPath::validate() const {
  if (!target_w.allFinite())
    fail(ErrorCode::InvalidArgument, "camera path: target_w must be finite");
  if (!std::isfinite(distance_m) || distance_m <= 0.0)
    fail(ErrorCode::InvalidArgument, "camera path: distance_m must be > 0, got {}", distance_m);
  if (!std::isfinite(azimuth_rad) || !std::isfinite(sweep_rad))
    fail(ErrorCode::InvalidArgument, "camera path: azimuth_rad and sweep_rad must be finite");
  // The camera must never look straight up or down (the image-up direction would be undefined).
  if (!std::isfinite(elevation_rad) || !std::isfinite(elevation_swing_rad) ||
      std::abs(elevation_rad) + std::abs(elevation_swing_rad) >= 1.5)
    fail(ErrorCode::InvalidArgument,
         "camera path: |elevation_rad| + |elevation_swing_rad| must stay below 1.5 rad, got {} + "
         "{}",
         elevation_rad, elevation_swing_rad);
  if (!std::isfinite(distance_swing) || distance_swing < 0.0 || distance_swing >= 0.9)
    fail(ErrorCode::InvalidArgument, "camera path: distance_swing must be in [0, 0.9), got {}",
         distance_swing);
  if (!std::isfinite(target_wobble_m) || target_wobble_m < 0.0)
    fail(ErrorCode::InvalidArgument, "camera path: target_wobble_m must be >= 0, got {}",
         target_wobble_m);
}

std::string CameraPath::to_string() const {
  return fmt::format(
      "{} target=({:.3f}, {:.3f}, {:.3f}) distance={:.3f} m azimuth={:.3f} rad sweep={:.3f} rad "
      "elevation={:.3f}+-{:.3f} rad distance_swing={:.3f} wobble={:.3f} m",
      kind == PathKind::Arc ? "arc" : "orbit", target_w.x(), target_w.y(), target_w.z(), distance_m,
      azimuth_rad, sweep_rad, elevation_rad, elevation_swing_rad, distance_swing, target_wobble_m);
}

Pose camera_pose(const CameraPath& path, double s) {
  const double w = 2.0 * std::numbers::pi * s;
  const bool orbit = path.kind == PathKind::Orbit;
  const double azimuth = path.azimuth_rad + (orbit ? w : path.sweep_rad * std::sin(w));
  const double elevation =
      path.elevation_rad + path.elevation_swing_rad * std::sin(orbit ? w : 2 * w);
  const double distance = path.distance_m * (1.0 + path.distance_swing * std::sin(2 * w));
  const Eigen::Vector3d target =
      path.target_w +
      path.target_wobble_m * Eigen::Vector3d(std::sin(2 * w), std::sin(3 * w), 0.5 * std::sin(w));
  const Eigen::Vector3d offset(std::cos(elevation) * std::cos(azimuth),
                               std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
  return look_at(target + distance * offset, target, Eigen::Vector3d::UnitZ());
}

std::vector<StampedPose> make_trajectory(const CameraPath& path, std::size_t frames, double fps) {
  path.validate();
  if (!std::isfinite(fps) || fps <= 0.0)
    fail(ErrorCode::InvalidArgument, "trajectory: fps must be > 0, got {}", fps);
  std::vector<StampedPose> poses(frames);
  for (std::size_t i = 0; i < frames; ++i) {
    poses[i].timestamp_s = static_cast<double>(i) / fps;
    poses[i].T_wc = camera_pose(path, static_cast<double>(i) / static_cast<double>(frames));
  }
  return poses;
}

}  // namespace hivox

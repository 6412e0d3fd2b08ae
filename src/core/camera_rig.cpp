#include "hivox/core/camera_rig.h"

#include <cmath>

#include <fmt/format.h>

#include "hivox/core/error.h"

namespace hivox {

CameraRig CameraRig::registered(const PinholeCamera& camera) {
  CameraRig rig;
  rig.depth_camera = camera;
  rig.color_camera = camera;
  return rig;
}

void CameraRig::validate(const std::string& what) const {
  depth_camera.validate(what + ": depth camera");
  if (!std::isfinite(depth_scale) || depth_scale < 0.0)
    fail(ErrorCode::InvalidArgument, "{}: depth_scale must be >= 0 raw units per metre, got {}",
         what, depth_scale);
  if (!T_color_depth.matrix().allFinite())
    fail(ErrorCode::InvalidArgument, "{}: the colour camera's pose must be finite", what);
}

void DepthRange::validate(const std::string& what) const {
  if (!std::isfinite(min_m) || min_m < 0.0f)
    fail(ErrorCode::InvalidArgument, "{}: min_m must be >= 0 metres, got {}", what, min_m);
  if (!std::isfinite(max_m) || max_m <= min_m)
    fail(ErrorCode::InvalidArgument, "{}: max_m must be > min_m ({} m), got {}", what, min_m,
         max_m);
}

std::string DepthRange::to_string() const {
  return fmt::format("{:.2f}-{:.2f} m", min_m, max_m);
}

}  // namespace hivox

#pragma once
/// @file
/// `intrinsics.json`: `{"fx", "fy", "cx", "cy", "width", "height", "depth_scale"}` (+ optional
/// `note`, `distortion_k1k2p1p2k3`, 4 or 5 lens distortion coefficients in OpenCV's order, and
/// `depth_noise`: the depth's noise model, "kinect" or "none" (rendered, noise-free depth) or
/// `{"sigma_min_m", "quadratic_per_m", "z0_m"}`; the refinement and tracking take it as the
/// dataset's own).

#include <filesystem>
#include <optional>
#include <string>

#include "hivox/core/camera.h"
#include "hivox/core/sensor_noise.h"

namespace hivox {

struct IntrinsicsFile {
  PinholeCamera camera;
  double depth_scale = 0;                  ///< raw depth units per metre; 0 when the file has none
  LensDistortion distortion;               ///< none when the file has none
  std::optional<SensorNoise> depth_noise;  ///< unset when the file has none
  std::string note;
};

/// Reads and validates an intrinsics file. Errors name the file and the bad field.
IntrinsicsFile read_intrinsics_json(const std::filesystem::path& path);
void write_intrinsics_json(const std::filesystem::path& path, const IntrinsicsFile& intrinsics);

}  // namespace hivox

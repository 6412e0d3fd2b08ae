#pragma once
/// @file
/// Pinhole camera model (OpenCV axes: x right, y down, z forward). A negative `fy` (as in
/// ICL-NUIM) is legal: it mirrors the image vertically and every function here handles it.

#include <string>

#include "hivox/core/hd.h"
#include "hivox/core/math.h"

namespace hivox {

struct PinholeCamera {
  float fx = 0;    ///< focal length along x, pixels (> 0)
  float fy = 0;    ///< focal length along y, pixels (non-zero; negative flips y)
  float cx = 0;    ///< principal point x, pixels
  float cy = 0;    ///< principal point y, pixels
  int width = 0;   ///< image width, pixels
  int height = 0;  ///< image height, pixels

  /// Projects a camera-frame point (z > 0) to continuous pixel coordinates.
  HIVOX_HD Vec2f project(const Vec3f& p_c) const {
    const float inv_z = 1.0f / p_c.z;
    return {fx * p_c.x * inv_z + cx, fy * p_c.y * inv_z + cy};
  }
  /// Back-projects pixel (u, v) at depth z (metres along the optical axis) to the camera frame.
  HIVOX_HD Vec3f unproject(float u, float v, float z) const {
    return {(u - cx) / fx * z, (v - cy) / fy * z, z};
  }
  /// Unit-depth ray (z = 1) through pixel (u, v).
  HIVOX_HD Vec3f ray(float u, float v) const { return unproject(u, v, 1.0f); }
  HIVOX_HD bool contains(float u, float v) const {
    return u >= 0.0f && v >= 0.0f && u <= static_cast<float>(width) - 1.0f &&
           v <= static_cast<float>(height) - 1.0f;
  }

  /// Camera for an image resampled by `factor` (0.5 = half resolution), pixel centres kept.
  PinholeCamera scaled(float factor) const;
  /// Camera for an image subsampled by an integer `factor` (2 = half resolution): width and
  /// height divided rounding down (what 2x2 block averaging of an odd-sized image gives), pixel
  /// centres kept.
  PinholeCamera subsampled(int factor) const;

  /// Throws `Error(InvalidArgument)` naming the first bad field. `what` prefixes the message
  /// (e.g. the file the intrinsics came from).
  void validate(const std::string& what = "camera") const;
  std::string to_string() const;
  bool operator==(const PinholeCamera&) const = default;
};

/// Radial-tangential lens distortion (Brown-Conrady, in OpenCV's order k1, k2, p1, p2, k3) of
/// normalised image coordinates (x, y) = ((u - cx) / fx, (v - cy) / fy). All zero = none.
/// Frames are undistorted when they are read (see `Undistorter`): everything after works on an
/// ideal pinhole camera.
struct LensDistortion {
  float k1 = 0, k2 = 0, p1 = 0, p2 = 0, k3 = 0;

  HIVOX_HD bool none() const {
    return k1 == 0.0f && k2 == 0.0f && p1 == 0.0f && p2 == 0.0f && k3 == 0.0f;
  }
  /// Where the ideal normalised point `xy` appears in the distorted image (normalised).
  HIVOX_HD Vec2f distort(const Vec2f& xy) const {
    const float x = xy.x, y = xy.y;
    const float r2 = x * x + y * y;
    const float radial = 1.0f + r2 * (k1 + r2 * (k2 + r2 * k3));
    return {x * radial + 2.0f * p1 * x * y + p2 * (r2 + 2.0f * x * x),
            y * radial + p1 * (r2 + 2.0f * y * y) + 2.0f * p2 * x * y};
  }
  /// Throws `Error(InvalidArgument)` when a coefficient is not finite; `what` prefixes it.
  void validate(const std::string& what = "lens distortion") const;
  std::string to_string() const;
};

}  // namespace hivox

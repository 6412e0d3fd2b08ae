#pragma once
/// @file
/// Removing lens distortion from images as they are read, so that every later stage sees an
/// ideal pinhole camera with the calibrated intrinsics.

#include <cstdint>
#include <vector>

#include "hivox/core/camera.h"
#include "hivox/core/image.h"

namespace hivox {

/// Resamples images of a distorted camera into its ideal pinhole image: output pixel (u, v)
/// takes the input where the ray of (u, v) appears under the distortion. The source positions
/// are computed once.
class Undistorter {
 public:
  Undistorter(const PinholeCamera& camera, const LensDistortion& distortion);

  const PinholeCamera& camera() const { return camera_; }
  const LensDistortion& distortion() const { return distortion_; }
  /// Output pixels whose source lies outside the input image (they come out invalid / black).
  int64_t outside_pixels() const { return outside_; }

  /// Depth from the nearest input pixel: interpolating would invent depth between a foreground
  /// and a background surface. 0 (invalid) where the source is outside.
  DepthImage depth(const DepthImage& in) const;
  /// Colour interpolated bilinearly; black where the source is outside.
  ColorImage color(const ColorImage& in) const;

 private:
  void check_size(int width, int height, const char* what) const;

  PinholeCamera camera_;
  LensDistortion distortion_;
  std::vector<Vec2f> source_;  ///< per output pixel: continuous input position (-2, -2): outside
  int64_t outside_ = 0;
};

}  // namespace hivox

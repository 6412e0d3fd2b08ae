#pragma once
/// @file
/// Axial depth noise of an RGB-D sensor as a function of depth. The refinement criterion compares
/// surface detail with it (what the sensor cannot resolve is not structure worth finer voxels)
/// and tracking scales its robust residual weights by it.

#include "hivox/core/hd.h"

namespace hivox {

/// sigma(z) = sigma_min_m + quadratic_per_m * (z - z0_m)^2 for z > z0_m, sigma_min_m nearer
/// (Nguyen et al. 2012 for Kinect-class sensors).
struct SensorNoise {
  float sigma_min_m = 0.0012f;
  float quadratic_per_m = 0.0019f;
  float z0_m = 0.4f;
  /// sigma(z) in metres; a model with all zeros is a perfect sensor.
  HIVOX_HD float sigma_m(float z_m) const {
    const float dz = z_m > z0_m ? z_m - z0_m : 0.0f;
    return sigma_min_m + quadratic_per_m * dz * dz;
  }
  static SensorNoise kinect() { return {}; }
  static SensorNoise none() { return {0.0f, 0.0f, 0.0f}; }
};

}  // namespace hivox

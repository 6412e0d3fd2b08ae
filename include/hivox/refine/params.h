#pragma once
/// @file
/// Adaptive resolution (DESIGN §4): when blocks split into 8 finer blocks or merge back.

#include <string>
#include <string_view>

namespace hivox {

enum class RefineCriterion {
  /// RMS (metres) of how far the TSDF near the surface departs from linear between neighbouring
  /// voxels: exactly the detail a merge into the coarser level would lose. Zero for planes,
  /// ~s^2/(2R) for a surface of curvature radius R at voxel size s, large at edges and fine
  /// structure. Only voxels observed `min_weight` times count, so fresh noise does not split.
  Detail,
  /// The paper's criterion: determinant of the covariance of the unit TSDF gradients (forward
  /// differences over the inner 7^3 voxels, sums divided by 512).
  DetCov,
};
std::string_view to_string(RefineCriterion criterion);
/// Parses "detail" or "det-cov"; throws `Error(InvalidArgument)` otherwise.
RefineCriterion parse_refine_criterion(std::string_view name);

/// Axial depth noise of the sensor as a function of depth, sigma(z) = sigma_min_m +
/// quadratic_per_m * (z - z0_m)^2 (Nguyen et al. 2012 for Kinect-class sensors). The Detail
/// criterion compares a block's detail with it: what the sensor cannot resolve at that depth is
/// not structure worth finer voxels.
struct SensorNoise {
  float sigma_min_m = 0.0012f;
  float quadratic_per_m = 0.0019f;
  float z0_m = 0.4f;
  /// sigma(z) in metres; a model with all zeros is a perfect sensor.
  float sigma_m(float z_m) const {
    const float dz = z_m > z0_m ? z_m - z0_m : 0.0f;
    return sigma_min_m + quadratic_per_m * dz * dz;
  }
  static SensorNoise kinect() { return {}; }
  static SensorNoise none() { return {0.0f, 0.0f, 0.0f}; }
};

struct RefineParams {
  RefineCriterion criterion = RefineCriterion::Detail;
  /// Split a block (not at the finest level) whose complexity exceeds
  /// max(split_threshold, split_noise_factor * sigma(z)) at its depth z. Metres for Detail, a
  /// determinant for DetCov (which ignores the noise terms).
  float split_threshold = 0.0008f;
  /// Merge 8 sibling leaves back when each one's complexity is below
  /// max(merge_threshold, merge_noise_factor * sigma(z)) (< the split level: hysteresis).
  float merge_threshold = 0.0004f;
  SensorNoise noise = SensorNoise::kinect();
  float split_noise_factor = 0.4f;
  float merge_noise_factor = 0.2f;
  int every_n_frames = 1;  ///< refine after every n-th frame
  int min_weight = 5;      ///< voxels observed fewer times do not count in the criterion
  /// Frames integrated into a block since its content was created (allocation, split, merge)
  /// before it is judged: freshly interpolated blocks carry no detail of their own yet.
  int min_updates = 10;
  /// Children start with the parent's interpolated weight times this, so that new fine
  /// observations soon outweigh the interpolated coarse values.
  float split_weight_scale = 0.5f;

  /// The paper's settings: DetCov, one threshold 1e-4 for both (no hysteresis), every voxel
  /// observed at least once counts, every frame, no noise model.
  static RefineParams paper();

  /// Complexity above which a block at depth z_m splits, and below which it may merge.
  float split_level(float z_m) const;
  float merge_level(float z_m) const;

  void validate() const;
  std::string to_string() const;
};

}  // namespace hivox

#pragma once
/// @file
/// Camera tracking parameters (DESIGN §6): depth preprocessing, the coarse-to-fine
/// point-to-plane ICP against the model's raycast, and the tracking-quality verdict.

#include <string>
#include <string_view>
#include <vector>

#include "hivox/core/sensor_noise.h"

namespace hivox {

/// Verdict on one frame's pose. A lost frame keeps the previous pose and is not fused.
enum class TrackingQuality {
  Good,  ///< enough well-spread correspondences agreeing with the model
  Poor,  ///< a pose was found but few points agree or the geometry constrains it badly
  Lost,  ///< no trustworthy pose: too few correspondences, residual too large, or a wild jump
};
std::string_view to_string(TrackingQuality quality);

/// How residuals (in units of the sensor noise at their depth) are weighted.
enum class RobustLoss {
  None,   ///< plain least squares
  Huber,  ///< quadratic up to `robust_scale` sigmas, linear beyond
  Tukey,  ///< biweight: residuals beyond `robust_scale` sigmas have no weight
};
std::string_view to_string(RobustLoss loss);
/// Parses "none", "huber" or "tukey"; throws `Error(InvalidArgument)` otherwise.
RobustLoss parse_robust_loss(std::string_view name);

struct TrackParams {
  // Depth preprocessing.
  int bilateral_radius_px = 2;            ///< window half-size of the bilateral filter (0: off)
  float bilateral_sigma_px = 2.0f;        ///< spatial sigma
  float bilateral_sigma_depth_m = 0.03f;  ///< range sigma: depths farther apart do not mix
  /// Neighbours whose depth differs by more than this fraction of the depth are across a
  /// discontinuity: no normal there, and no averaging into coarser pyramid levels.
  float max_depth_jump_ratio = 0.05f;

  // ICP.
  /// Gauss-Newton iterations per pyramid level, finest first; its length is the number of
  /// levels (each halves the resolution).
  std::vector<int> iterations = {4, 6, 10};
  /// Correspondences farther apart than this (metres, at the finest level; doubled per coarser
  /// level) or with normals more than `max_normal_angle_deg` apart are rejected.
  float max_distance_m = 0.05f;
  float max_normal_angle_deg = 30.0f;
  RobustLoss loss = RobustLoss::Huber;
  /// Robust threshold in units of the residual's sigma: sqrt(sigma(z)^2 + residual_floor_m^2),
  /// sigma(z) the sensor's axial noise at the point's depth.
  float robust_scale = 2.0f;
  float residual_floor_m = 0.002f;
  SensorNoise noise = SensorNoise::kinect();
  /// Start from the previous pose moved by the previous frame-to-frame motion (constant
  /// velocity) instead of the previous pose itself.
  bool constant_velocity = true;
  /// The model is raycast at 1/model_subsample of the frame's resolution (1, 2 or 4): the
  /// raycast is the costliest stage of the loop, and projective association needs no more than
  /// one model pixel per 2x2 frame pixels to find the right plane.
  int model_subsample = 2;
  /// Iterations stop when an update moves less than this (metres and radians).
  float convergence_step = 1e-5f;

  // Verdict (measured at the finest level).
  float lost_inlier_ratio = 0.15f;  ///< inliers / valid pixels below this: lost
  float poor_inlier_ratio = 0.4f;   ///< below this: poor
  float lost_rms_m = 0.02f;         ///< RMS point-to-plane residual of inliers above this: lost
  /// Smallest / largest eigenvalue of the normalised Gauss-Newton system below this: poor
  /// (a direction of motion the geometry does not constrain, e.g. sliding along a wall).
  float poor_condition = 1e-3f;
  float lost_jump_m = 0.3f;  ///< a pose this far (or `lost_jump_deg`) from the start: lost
  float lost_jump_deg = 45.0f;

  int levels() const { return static_cast<int>(iterations.size()); }
  void validate() const;
  std::string to_string() const;
};

}  // namespace hivox

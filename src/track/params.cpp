#include "hivox/track/params.h"

#include <cmath>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "hivox/core/error.h"

namespace hivox {

std::string_view to_string(TrackingQuality quality) {
  switch (quality) {
    case TrackingQuality::Good:
      return "good";
    case TrackingQuality::Poor:
      return "poor";
    case TrackingQuality::Lost:
      return "lost";
  }
  return "?";
}

std::string_view to_string(RobustLoss loss) {
  switch (loss) {
    case RobustLoss::None:
      return "none";
    case RobustLoss::Huber:
      return "huber";
    case RobustLoss::Tukey:
      return "tukey";
  }
  return "?";
}

RobustLoss parse_robust_loss(std::string_view name) {
  if (name == "none") return RobustLoss::None;
  if (name == "huber") return RobustLoss::Huber;
  if (name == "tukey") return RobustLoss::Tukey;
  fail(ErrorCode::InvalidArgument, "unknown robust loss '{}' (expected none, huber or tukey)",
       name);
}

void TrackParams::validate() const {
  if (model_subsample != 1 && model_subsample != 2 && model_subsample != 4)
    fail(ErrorCode::InvalidArgument, "track model_subsample must be 1, 2 or 4, got {}",
         model_subsample);
  auto positive = [](float v, const char* name) {
    if (!std::isfinite(v) || v <= 0.0f)
      fail(ErrorCode::InvalidArgument, "track {} must be > 0, got {}", name, v);
  };
  if (bilateral_radius_px < 0 || bilateral_radius_px > 8)
    fail(ErrorCode::InvalidArgument, "track bilateral_radius_px must be in [0, 8], got {}",
         bilateral_radius_px);
  positive(bilateral_sigma_px, "bilateral_sigma_px");
  positive(bilateral_sigma_depth_m, "bilateral_sigma_depth_m");
  positive(max_depth_jump_ratio, "max_depth_jump_ratio");
  if (iterations.empty() || iterations.size() > 5)
    fail(ErrorCode::InvalidArgument, "track iterations: 1 to 5 pyramid levels, got {}",
         iterations.size());
  for (int it : iterations)
    if (it < 0 || it > 100)
      fail(ErrorCode::InvalidArgument, "track iterations per level must be in [0, 100], got {}",
           fmt::join(iterations, ","));
  positive(max_distance_m, "max_distance_m");
  if (!(max_normal_angle_deg > 0.0f && max_normal_angle_deg <= 90.0f))
    fail(ErrorCode::InvalidArgument, "track max_normal_angle_deg must be in (0, 90], got {}",
         max_normal_angle_deg);
  positive(robust_scale, "robust_scale");
  if (!(residual_floor_m >= 0.0f))
    fail(ErrorCode::InvalidArgument, "track residual_floor_m must be >= 0, got {}",
         residual_floor_m);
  if (residual_floor_m == 0.0f && noise.sigma_m(1.0f) == 0.0f)
    fail(ErrorCode::InvalidArgument,
         "track residual_floor_m must be > 0 with a noise-free sensor model");
  positive(convergence_step, "convergence_step");
  if (!(lost_inlier_ratio >= 0.0f && lost_inlier_ratio <= poor_inlier_ratio &&
        poor_inlier_ratio <= 1.0f))
    fail(ErrorCode::InvalidArgument,
         "track inlier ratios must satisfy 0 <= lost ({}) <= poor ({}) <= 1", lost_inlier_ratio,
         poor_inlier_ratio);
  positive(lost_rms_m, "lost_rms_m");
  if (!(poor_condition >= 0.0f && poor_condition < 1.0f))
    fail(ErrorCode::InvalidArgument, "track poor_condition must be in [0, 1), got {}",
         poor_condition);
  positive(lost_jump_m, "lost_jump_m");
  positive(lost_jump_deg, "lost_jump_deg");
}

std::string TrackParams::to_string() const {
  return fmt::format(
      "point-to-plane ICP, {} levels (iterations {} finest first), {} loss at {:g} sigma, "
      "reject > {:.0f} mm or > {:.0f} deg, bilateral r {} px, model 1/{} resolution, {}",
      levels(), fmt::join(iterations, "/"), hivox::to_string(loss), robust_scale,
      max_distance_m * 1000.0f, max_normal_angle_deg, bilateral_radius_px, model_subsample,
      constant_velocity ? "constant-velocity prior" : "previous pose as start");
}

}  // namespace hivox

#include "hivox/refine/params.h"

#include <cmath>

#include <fmt/format.h>

#include "hivox/core/error.h"
#include "refine/refine_kernels.h"

namespace hivox {

std::string_view to_string(RefineCriterion criterion) {
  switch (criterion) {
    case RefineCriterion::Detail:
      return "detail";
    case RefineCriterion::DetCov:
      return "det-cov";
  }
  return "unknown";
}

RefineCriterion parse_refine_criterion(std::string_view name) {
  if (name == "detail") return RefineCriterion::Detail;
  if (name == "det-cov") return RefineCriterion::DetCov;
  fail(ErrorCode::InvalidArgument, "refine criterion must be 'detail' or 'det-cov', got '{}'",
       name);
}

RefineParams RefineParams::paper() {
  RefineParams p;
  p.criterion = RefineCriterion::DetCov;
  p.split_threshold = 1e-4f;
  p.merge_threshold = 1e-4f;
  p.min_weight = 1;
  p.min_updates = 1;
  p.split_unmeshable_cells = 0;
  p.noise = SensorNoise::none();
  return p;
}

kernels::RefineLevels kernels::refine_levels(const RefineParams& p) {
  return {p.split_threshold,   p.merge_threshold, p.split_noise_factor,
          p.merge_noise_ratio, p.settled_weight,  p.criterion == RefineCriterion::Detail};
}

float RefineParams::split_level(const SensorNoise& sensor, float z_m, float mean_weight) const {
  return kernels::split_level(kernels::refine_levels(*this), sensor.sigma_m(z_m), mean_weight);
}

float RefineParams::merge_level(const SensorNoise& sensor, float z_m) const {
  return kernels::merge_level(kernels::refine_levels(*this), sensor.sigma_m(z_m));
}

void RefineParams::validate() const {
  if (!std::isfinite(split_threshold) || split_threshold <= 0.0f)
    fail(ErrorCode::InvalidArgument, "refine split_threshold must be > 0, got {}", split_threshold);
  if (!std::isfinite(merge_threshold) || merge_threshold < 0.0f ||
      merge_threshold > split_threshold)
    fail(ErrorCode::InvalidArgument,
         "refine merge_threshold must be in [0, split_threshold = {}], got {}", split_threshold,
         merge_threshold);
  if (every_n_frames < 1)
    fail(ErrorCode::InvalidArgument, "refine every_n_frames must be >= 1, got {}", every_n_frames);
  if (min_weight < 1 || min_weight > 65535)
    fail(ErrorCode::InvalidArgument, "refine min_weight must be in [1, 65535], got {}", min_weight);
  if (!(settled_weight >= 1.0f))
    fail(ErrorCode::InvalidArgument, "refine settled_weight must be >= 1, got {}", settled_weight);
  if (split_unmeshable_cells < 0 || split_unmeshable_cells > 343)
    fail(ErrorCode::InvalidArgument,
         "refine split_unmeshable_cells must be in [0, 343] (the cells of a block), got {}",
         split_unmeshable_cells);
  if (unmeshable_min_weight < 1)
    fail(ErrorCode::InvalidArgument, "refine unmeshable_min_weight must be >= 1, got {}",
         unmeshable_min_weight);
  if (min_samples < 1)
    fail(ErrorCode::InvalidArgument, "refine min_samples must be >= 1, got {}", min_samples);
  if (min_updates < 0 || min_updates > 65535)
    fail(ErrorCode::InvalidArgument, "refine min_updates must be in [0, 65535], got {}",
         min_updates);
  if (noise &&
      !(noise->sigma_min_m >= 0.0f && noise->quadratic_per_m >= 0.0f && std::isfinite(noise->z0_m)))
    fail(ErrorCode::InvalidArgument,
         "refine sensor noise terms must be >= 0, got {} + {} (z - {})^2", noise->sigma_min_m,
         noise->quadratic_per_m, noise->z0_m);
  if (!(split_noise_factor >= 0.0f) || !std::isfinite(split_noise_factor))
    fail(ErrorCode::InvalidArgument, "refine split_noise_factor must be >= 0, got {}",
         split_noise_factor);
  if (!(merge_noise_ratio >= 0.0f && merge_noise_ratio <= 1.0f))
    fail(ErrorCode::InvalidArgument, "refine merge_noise_ratio must be in [0, 1], got {}",
         merge_noise_ratio);
  if (!(split_weight_scale > 0.0f && split_weight_scale <= 1.0f))
    fail(ErrorCode::InvalidArgument, "refine split_weight_scale must be in (0, 1], got {}",
         split_weight_scale);
}

std::string RefineParams::to_string(const std::optional<SensorNoise>& sensor) const {
  const bool metres = criterion == RefineCriterion::Detail;
  // The noise model in use: this one's own, else the sensor's (unknown here: assume noisy).
  const std::optional<SensorNoise> n = noise ? noise : sensor;
  const bool noisy = metres && (!n || n->sigma_min_m > 0.0f || n->quadratic_per_m > 0.0f);
  return fmt::format(
      "criterion {}, split > {:.3g}{}{}, merge < {:.3g}{}{}, every {} frame{}, min weight {}, min "
      "updates {}{}",
      hivox::to_string(criterion), metres ? split_threshold * 1000.0f : split_threshold,
      metres ? " mm" : "", noisy ? fmt::format(" or {} sigma(z)", split_noise_factor) : "",
      metres ? merge_threshold * 1000.0f : merge_threshold, metres ? " mm" : "",
      noisy ? fmt::format(" or {:g} sigma(z)", merge_noise_ratio * split_noise_factor) : "",
      every_n_frames, every_n_frames > 1 ? "s" : "", min_weight, min_updates,
      split_unmeshable_cells > 0
          ? fmt::format(", split on {} unmeshable cells", split_unmeshable_cells)
          : std::string());
}

}  // namespace hivox

#include "hivox/fusion/params.h"

#include <cmath>

#include <fmt/format.h>

#include "hivox/core/error.h"
#include "hivox/core/log.h"
#include "hivox/map/params.h"

namespace hivox {

std::string_view to_string(DepthSampling sampling) {
  switch (sampling) {
    case DepthSampling::Nearest:
      return "nearest";
    case DepthSampling::Bilinear:
      return "bilinear";
  }
  return "?";
}

DepthSampling parse_depth_sampling(std::string_view name) {
  if (name == "nearest") return DepthSampling::Nearest;
  if (name == "bilinear") return DepthSampling::Bilinear;
  fail(ErrorCode::InvalidArgument, "depth sampling must be 'nearest' or 'bilinear', got '{}'",
       name);
}

void FusionParams::validate() const {
  if (!std::isfinite(truncation_m) || truncation_m <= 0.0f || truncation_m > 1.0f)
    fail(ErrorCode::InvalidArgument, "truncation_m must be in (0, 1] metres, got {}", truncation_m);
  if (max_weight < 1 || max_weight > 65535)
    fail(ErrorCode::InvalidArgument, "max_weight must be in [1, 65535], got {}", max_weight);
  if (!std::isfinite(min_depth_m) || min_depth_m < 0.0f)
    fail(ErrorCode::InvalidArgument, "min_depth_m must be >= 0 metres, got {}", min_depth_m);
  if (!std::isfinite(max_depth_m) || max_depth_m <= min_depth_m)
    fail(ErrorCode::InvalidArgument, "max_depth_m must be > min_depth_m ({} m), got {}",
         min_depth_m, max_depth_m);
}

void FusionParams::check_against(const MapParams& map) const {
  const float finest = map.voxel_size_m;
  const float coarsest = map.voxel_size_at(map.levels - 1);
  if (truncation_m < finest)
    log::warn("truncation_m {:.4f} m is below the voxel size {:.4f} m: surfaces will have holes",
              truncation_m, finest);
  else if (truncation_m < 2.0f * coarsest)
    log::warn(
        "truncation_m {:.4f} m is less than 2x the coarsest voxel size ({:.4f} m): the coarsest "
        "level sees a band of about one voxel and meshes may have holes; use >= {:.4f} m",
        truncation_m, coarsest, 2.0f * coarsest);
}

std::string FusionParams::to_string() const {
  return fmt::format(
      "truncation {:.1f} mm, max weight {}, depth {:.2f}-{:.2f} m, colour {}, depth sampling {}",
      truncation_m * 1000.0f, max_weight, min_depth_m, max_depth_m, integrate_color ? "on" : "off",
      hivox::to_string(depth_sampling));
}

}  // namespace hivox

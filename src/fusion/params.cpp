#include "hivox/fusion/params.h"

#include <cmath>

#include <fmt/format.h>

#include "hivox/core/error.h"

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
  if (max_weight < 1 || max_weight > 65535)
    fail(ErrorCode::InvalidArgument, "max_weight must be in [1, 65535], got {}", max_weight);
  depth_range.validate("fusion depth_range");
}

std::string FusionParams::to_string() const {
  return fmt::format("max weight {}, depth {}, colour {}, depth sampling {}", max_weight,
                     depth_range.to_string(), integrate_color ? "on" : "off",
                     hivox::to_string(depth_sampling));
}

}  // namespace hivox

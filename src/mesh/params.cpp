#include "hivox/mesh/params.h"

#include <cmath>

#include <fmt/format.h>

#include "hivox/core/error.h"

namespace hivox {

void MeshParams::validate() const {
  if (!std::isfinite(min_weight) || min_weight < 1.0f || min_weight > 65535.0f)
    fail(ErrorCode::InvalidArgument,
         "min_weight must be in [1, 65535] observations (weight 0 is unobserved), got {}",
         min_weight);
}

std::string MeshParams::to_string() const {
  return fmt::format("min weight {}, normals {}, colour {}", min_weight,
                     compute_normals ? "on" : "off", with_color ? "on" : "off");
}

}  // namespace hivox

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
  if (bounds) bounds->validate("mesh bounds");
  if (min_piece_triangles < 0)
    fail(ErrorCode::InvalidArgument, "min_piece_triangles must be >= 0, got {}",
         min_piece_triangles);
}

std::string MeshParams::to_string() const {
  std::string s = fmt::format("min weight {}, normals {}, colour {}", min_weight,
                              compute_normals ? "on" : "off", with_color ? "on" : "off");
  if (bounds)
    s += fmt::format(", inside [{}, {}, {}] .. [{}, {}, {}] m", bounds->min_m.x, bounds->min_m.y,
                     bounds->min_m.z, bounds->max_m.x, bounds->max_m.y, bounds->max_m.z);
  if (min_piece_triangles > 0) s += fmt::format(", pieces of >= {} triangles", min_piece_triangles);
  return s;
}

}  // namespace hivox

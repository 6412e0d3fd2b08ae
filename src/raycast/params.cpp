#include "hivox/raycast/params.h"

#include <cmath>

#include <fmt/format.h>

#include "hivox/core/error.h"

namespace hivox {

void RaycastParams::validate() const {
  if (!std::isfinite(min_depth_m) || min_depth_m <= 0.0f)
    fail(ErrorCode::InvalidArgument, "raycast min_depth_m must be > 0 metres, got {}", min_depth_m);
  if (!std::isfinite(max_depth_m) || max_depth_m <= min_depth_m)
    fail(ErrorCode::InvalidArgument, "raycast max_depth_m must be > min_depth_m ({}), got {}",
         min_depth_m, max_depth_m);
  if (!std::isfinite(truncation_m) || truncation_m <= 0.0f)
    fail(ErrorCode::InvalidArgument, "raycast truncation_m must be > 0 metres, got {}",
         truncation_m);
  if (range_tile_px < 1 || range_tile_px > kMaxRangeTilePx)
    fail(ErrorCode::InvalidArgument, "range_tile_px must be in [1, {}], got {}", kMaxRangeTilePx,
         range_tile_px);
  if (!(step_fraction > 0.0f && step_fraction <= 1.0f))
    fail(ErrorCode::InvalidArgument, "step_fraction must be in (0, 1], got {}", step_fraction);
  if (!std::isfinite(hint_margin_mu) || hint_margin_mu < 0.0f)
    fail(ErrorCode::InvalidArgument,
         "raycast hint_margin_mu must be >= 0 truncation bands (finite), got {}", hint_margin_mu);
  if (!std::isfinite(hint_agreement_mu) || hint_agreement_mu < 0.0f)
    fail(ErrorCode::InvalidArgument,
         "raycast hint_agreement_mu must be >= 0 truncation bands (finite), got {}",
         hint_agreement_mu);
  if (min_weight < 1)
    fail(ErrorCode::InvalidArgument, "min_weight must be >= 1, got {}", min_weight);
}

std::string RaycastParams::to_string() const {
  return fmt::format("depth {:.2f}-{:.2f} m, truncation {:.1f} mm, tiles {} px, step {:.2f} mu",
                     min_depth_m, max_depth_m, truncation_m * 1000.0f, range_tile_px,
                     step_fraction);
}

}  // namespace hivox

#include "hivox/raycast/params.h"

#include <cmath>

#include <fmt/format.h>

#include "hivox/core/error.h"

namespace hivox {

void RaycastTuning::validate() const {
  if (range_tile_px < 1 || range_tile_px > kMaxRangeTilePx)
    fail(ErrorCode::InvalidArgument, "raycast tuning range_tile_px must be in [1, {}], got {}",
         kMaxRangeTilePx, range_tile_px);
}

void RaycastParams::validate() const {
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
  tuning.validate();
}

std::string RaycastParams::to_string() const {
  return fmt::format(
      "step {:.2f} mu, min weight {}, hints from {:g} mu ahead, agreeing within {:g} mu",
      step_fraction, min_weight, hint_margin_mu, hint_agreement_mu);
}

}  // namespace hivox

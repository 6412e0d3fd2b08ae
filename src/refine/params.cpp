#include "hivox/refine/params.h"

#include <cmath>

#include <fmt/format.h>

#include "hivox/core/error.h"

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
  return p;
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
  if (min_updates < 0 || min_updates > 65535)
    fail(ErrorCode::InvalidArgument, "refine min_updates must be in [0, 65535], got {}",
         min_updates);
  if (!(split_weight_scale > 0.0f && split_weight_scale <= 1.0f))
    fail(ErrorCode::InvalidArgument, "refine split_weight_scale must be in (0, 1], got {}",
         split_weight_scale);
}

std::string RefineParams::to_string() const {
  const bool metres = criterion == RefineCriterion::Detail;
  return fmt::format(
      "criterion {}, split > {}{}, merge < {}{}, every {} frame{}, min weight {}, min updates {}",
      hivox::to_string(criterion), metres ? split_threshold * 1000.0f : split_threshold,
      metres ? " mm" : "", metres ? merge_threshold * 1000.0f : merge_threshold,
      metres ? " mm" : "", every_n_frames, every_n_frames > 1 ? "s" : "", min_weight, min_updates);
}

}  // namespace hivox

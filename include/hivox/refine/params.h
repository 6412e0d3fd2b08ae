#pragma once
/// @file
/// Adaptive resolution (DESIGN §4): when blocks split into 8 finer blocks or merge back.

#include <string>
#include <string_view>

namespace hivox {

enum class RefineCriterion {
  /// RMS (metres) of how far the TSDF near the surface departs from linear between neighbouring
  /// voxels: exactly the detail a merge into the coarser level would lose. Zero for planes,
  /// ~s^2/(2R) for a surface of curvature radius R at voxel size s, large at edges and fine
  /// structure. Only voxels observed `min_weight` times count, so fresh noise does not split.
  Detail,
  /// The paper's criterion: determinant of the covariance of the unit TSDF gradients (forward
  /// differences over the inner 7^3 voxels, sums divided by 512).
  DetCov,
};
std::string_view to_string(RefineCriterion criterion);
/// Parses "detail" or "det-cov"; throws `Error(InvalidArgument)` otherwise.
RefineCriterion parse_refine_criterion(std::string_view name);

struct RefineParams {
  RefineCriterion criterion = RefineCriterion::Detail;
  /// Split a block (not at the finest level) whose complexity exceeds this. Metres for Detail,
  /// a determinant for DetCov.
  float split_threshold = 0.0008f;
  /// Merge 8 sibling leaves back when each one's complexity is below this (< split_threshold:
  /// hysteresis).
  float merge_threshold = 0.0004f;
  int every_n_frames = 1;  ///< refine after every n-th frame
  int min_weight = 5;      ///< voxels observed fewer times do not count in the criterion
  /// Frames integrated into a block since its content was created (allocation, split, merge)
  /// before it is judged: freshly interpolated blocks carry no detail of their own yet.
  int min_updates = 10;
  /// Children start with the parent's interpolated weight times this, so that new fine
  /// observations soon outweigh the interpolated coarse values.
  float split_weight_scale = 0.5f;

  /// The paper's settings: DetCov, one threshold 1e-4 for both (no hysteresis), every voxel
  /// observed at least once counts, every frame.
  static RefineParams paper();

  void validate() const;
  std::string to_string() const;
};

}  // namespace hivox

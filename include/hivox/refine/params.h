#pragma once
/// @file
/// Adaptive resolution (DESIGN §4): when blocks split into 8 finer blocks or merge back.

#include <optional>
#include <string>
#include <string_view>

#include "hivox/core/sensor_noise.h"

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
  /// Split a block (not at the finest level) whose complexity exceeds
  /// max(split_threshold, split_noise_factor * sigma(z)) at its depth z. Metres for Detail, a
  /// determinant for DetCov (which ignores the noise terms).
  float split_threshold = 0.0003f;
  /// Merge 8 sibling leaves back when each one's complexity is below
  /// max(merge_threshold, merge_noise_ratio * split_noise_factor * sigma(z)) (< the split level:
  /// hysteresis).
  float merge_threshold = 0.00015f;
  /// The sensor's axial noise sigma(z) the thresholds compare detail with. Unset: the rig's own
  /// model (CameraRig::depth_noise: none for noise-free synthetic depth, so that detail below
  /// the absolute thresholds is all that a perfect sensor needs).
  std::optional<SensorNoise> noise;
  float split_noise_factor = 0.25f;
  /// The merge level's noise term as a fraction of the split level's, in [0, 1]. 0.72 (0.18
  /// sigma(z) with the default split factor): walls seen at 2-3 m with Kinect noise settle at the
  /// coarsest level (81 % of their area on the noisy synthetic desk, 65 % with 0.48) at the same
  /// accuracy; on real fr1/rpy the block count changes by 1 % (BENCHMARKS.md).
  float merge_noise_ratio = 0.72f;
  /// Fused noise falls as 1/sqrt(observations): a block whose sampled voxels were observed n
  /// times on average (n < settled_weight) has its noise terms raised by sqrt(settled_weight /
  /// n), so it splits early only on detail well above its noise. 32 is measured (BENCHMARKS.md):
  /// on the noisy synthetic desk it gives the lowest error against the exact SDF; lower values
  /// keep more blocks fine (real fr1/rpy: 8 saves 60 % of the blocks, 24 82 %, 64 89 %).
  float settled_weight = 32.0f;
  /// Also split a settled block (not at the finest level) with at least this many cells whose
  /// surface the level cannot mesh (kernels::block_unmeshable_cells: an observed corner in front
  /// of the surface, an unobserved one), and merge 8 siblings only when the merged block would
  /// have fewer. Seen at grazing angles, a coarse cell's corners behind the surface are never
  /// updated and the surface there is lost; a finer level's are. 0: off. Replica office0 exact
  /// (docs/experiments.md): completeness against the true mesh +19 % -> +14 % of the fixed 2 mm
  /// grid's, for 7 % more blocks.
  int split_unmeshable_cells = 8;
  /// The observed corner of an unmeshable cell counts when observed at least this often: fewer
  /// observations at the band's edge are mostly depth noise (on the synthetic desk with Kinect
  /// noise, 1 doubled the blocks; 8 adds 8 %).
  int unmeshable_min_weight = 8;
  int every_n_frames = 2;  ///< refine after every n-th frame
  int min_weight = 2;      ///< voxels observed fewer times do not count in the criterion
  /// Detail: a block with fewer near-surface samples than this is not judged (stays as it is).
  int min_samples = 4;
  /// Frames integrated into a block since its content was created (allocation, split, merge)
  /// before it is judged: freshly interpolated blocks carry no detail of their own yet.
  int min_updates = 3;
  /// Children start with the parent's interpolated weight times this, so that new fine
  /// observations soon outweigh the interpolated coarse values.
  float split_weight_scale = 0.5f;

  /// The paper's settings: DetCov, one threshold 1e-4 for both (no hysteresis), every voxel
  /// observed at least once counts, every frame, no noise model.
  static RefineParams paper();

  /// Complexity above which a block at depth z_m whose voxels were observed `mean_weight` times
  /// splits (young blocks need more), and below which a block at depth z_m may merge (no extra
  /// caution for young blocks: noise makes them look complex, not simple). `sensor` is the noise
  /// model in use (`noise`, or the rig's).
  float split_level(const SensorNoise& sensor, float z_m, float mean_weight = 1e9f) const;
  float merge_level(const SensorNoise& sensor, float z_m) const;

  void validate() const;
  /// The settings in words; `sensor`: the rig's noise model, used where `noise` is unset.
  std::string to_string(const std::optional<SensorNoise>& sensor = std::nullopt) const;
};

}  // namespace hivox

#pragma once
/// @file
/// Absolute trajectory error (ATE) as the TUM RGB-D benchmark's `evaluate_ate.py` computes it:
/// estimated poses are associated with ground-truth poses by timestamp (`associate.py`, offset
/// 0), the estimated positions are rigidly aligned to the ground truth (rotation + translation,
/// no scale; Horn/Umeyama closed form on the matched positions), and the errors are the
/// distances between aligned estimated and ground-truth positions. Orientations are not compared.

#include <cstddef>
#include <string>
#include <vector>

#include "hivox/core/pose.h"

namespace hivox {

struct AteParams {
  /// Pairs whose timestamps differ by this much or more are never matched, seconds (TUM: 0.02).
  double max_dt_s = 0.02;
  /// Rigidly align the estimate to the ground truth before measuring; off compares raw positions.
  bool align = true;

  /// Throws `Error(InvalidArgument)` naming the bad field.
  void validate() const;
  std::string to_string() const;
};

/// One estimated pose matched to one ground-truth pose (indices into the inputs).
struct PoseMatch {
  std::size_t gt_index = 0;
  std::size_t est_index = 0;
  double dt_s = 0;  ///< |t_gt - t_est|, < max_dt_s
};

/// TUM's association rule: every pair with |t_gt - t_est| < `max_dt_s` is a candidate; pairs are
/// taken greedily by increasing |dt| (ties: earlier ground truth, then earlier estimate), each
/// pose at most once. Matches come back sorted by ground-truth timestamp. The inputs need not be
/// sorted; poses with equal timestamps stay separate poses (TUM's dict would keep the last one).
/// Throws `Error(InvalidArgument)` for a bad `max_dt_s` and `Error(InvalidData)` for a
/// non-finite timestamp.
std::vector<PoseMatch> associate_by_time(const std::vector<StampedPose>& gt,
                                         const std::vector<StampedPose>& est, double max_dt_s);

struct AteResult {
  double rmse_m = 0;    ///< sqrt(mean(e^2)): the number TUM reports as the ATE
  double mean_m = 0;    ///< mean(e)
  double median_m = 0;  ///< median(e) (mean of the two middle values for an even count)
  double std_m = 0;     ///< population standard deviation of e (numpy.std)
  double min_m = 0;
  double max_m = 0;
  std::size_t matched = 0;  ///< number of associated pose pairs
  /// The alignment applied: maps estimated positions into the ground-truth frame,
  /// p_gt ~ T_gt_est * p_est (identity when `AteParams::align` is off).
  Pose T_gt_est = Pose::Identity();
  std::vector<PoseMatch> matches;  ///< sorted by ground-truth timestamp
  std::vector<double> errors_m;    ///< |T_gt_est * p_est - p_gt| per entry of `matches`
};

/// ATE of `est` against `gt` (both camera-to-world; positions are the translations of T_wc).
/// Throws `Error(InvalidData)` when an input is empty, holds a non-finite timestamp or pose, or
/// when fewer than 3 pose pairs match within `params.max_dt_s` (the message says how many did);
/// `Error(InvalidArgument)` for bad `params`.
AteResult evaluate_ate(const std::vector<StampedPose>& gt, const std::vector<StampedPose>& est,
                       const AteParams& params = {});

}  // namespace hivox

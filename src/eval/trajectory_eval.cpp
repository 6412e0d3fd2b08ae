#include "hivox/eval/trajectory_eval.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string_view>
#include <tuple>

#include <fmt/format.h>
#include <Eigen/SVD>

#include "hivox/core/error.h"

namespace hivox {

namespace {

// Fewer pairs leave the rigid alignment (6 degrees of freedom) meaningless.
constexpr std::size_t kMinMatches = 3;

void check_finite(const std::vector<StampedPose>& poses, std::string_view what, bool check_pose) {
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const StampedPose& p = poses[i];
    if (!std::isfinite(p.timestamp_s))
      fail(ErrorCode::InvalidData, "{} pose {} has a non-finite timestamp ({})", what, i,
           p.timestamp_s);
    if (check_pose && !p.T_wc.matrix().allFinite())
      fail(ErrorCode::InvalidData, "{} pose {} (t = {:.6f} s) is not finite", what, i,
           p.timestamp_s);
  }
}

std::vector<std::size_t> order_by_time(const std::vector<StampedPose>& poses) {
  std::vector<std::size_t> order(poses.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return poses[a].timestamp_s < poses[b].timestamp_s;
  });
  return order;
}

// numpy.median: the mean of the two middle values for an even count.
double median_of(std::vector<double> v) {
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  const double upper = v[mid];
  if (v.size() % 2 == 1) return upper;
  const double lower = *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid));
  return 0.5 * (lower + upper);
}

// The rigid motion T minimising sum |T * from_i - to_i|^2, as evaluate_ate.py's align() computes
// it (Horn/Kabsch: SVD of the cross-covariance, reflection excluded). Written out with fixed-size
// matrices rather than Eigen::umeyama, which trips GCC 12's -Warray-bounds with -march=native.
Pose rigid_alignment(const Eigen::Matrix3Xd& from, const Eigen::Matrix3Xd& to) {
  const Eigen::Vector3d from_mean = from.rowwise().mean();
  const Eigen::Vector3d to_mean = to.rowwise().mean();
  Eigen::Matrix3d W = Eigen::Matrix3d::Zero();  // sum of (from_i - mean)(to_i - mean)^T
  for (Eigen::Index i = 0; i < from.cols(); ++i)
    W += (from.col(i) - from_mean) * (to.col(i) - to_mean).transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(W.transpose(),
                                              Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0) S(2, 2) = -1;
  Pose T = Pose::Identity();
  T.linear() = svd.matrixU() * S * svd.matrixV().transpose();
  T.translation() = to_mean - T.linear() * from_mean;
  return T;
}

}  // namespace

void AteParams::validate() const {
  if (!std::isfinite(max_dt_s) || max_dt_s <= 0.0)
    fail(ErrorCode::InvalidArgument, "ATE max_dt_s must be > 0 seconds, got {}", max_dt_s);
}

std::string AteParams::to_string() const {
  return fmt::format("max dt {:.3f} s, {}", max_dt_s,
                     align ? "rigid alignment (rotation + translation, no scale)" : "no alignment");
}

std::vector<PoseMatch> associate_by_time(const std::vector<StampedPose>& gt,
                                         const std::vector<StampedPose>& est, double max_dt_s) {
  AteParams{.max_dt_s = max_dt_s}.validate();
  check_finite(gt, "ground-truth", false);
  check_finite(est, "estimated", false);
  const std::vector<std::size_t> gt_order = order_by_time(gt);
  const std::vector<std::size_t> est_order = order_by_time(est);

  // All candidate pairs, found with a window sliding over the sorted ground truth. TUM builds the
  // same list from all n*m pairs; the window only skips pairs that fail |dt| < max_dt. Floating-
  // point subtraction is monotonic, so the window's edges never pass a pair that would qualify.
  std::vector<PoseMatch> candidates;
  std::size_t first = 0;
  for (const std::size_t e : est_order) {
    const double t_est = est[e].timestamp_s;
    while (first < gt_order.size() && t_est - gt[gt_order[first]].timestamp_s >= max_dt_s) ++first;
    for (std::size_t k = first; k < gt_order.size(); ++k) {
      const std::size_t g = gt_order[k];
      if (gt[g].timestamp_s - t_est >= max_dt_s) break;
      const double dt = std::abs(gt[g].timestamp_s - t_est);
      if (dt < max_dt_s) candidates.push_back({g, e, dt});
    }
  }
  // associate.py sorts (|dt|, t_gt, t_est) tuples; indices make equal timestamps deterministic.
  const auto key = [&](const PoseMatch& m) {
    return std::make_tuple(m.dt_s, gt[m.gt_index].timestamp_s, est[m.est_index].timestamp_s,
                           m.gt_index, m.est_index);
  };
  std::sort(candidates.begin(), candidates.end(),
            [&](const PoseMatch& a, const PoseMatch& b) { return key(a) < key(b); });

  std::vector<bool> gt_used(gt.size(), false);
  std::vector<bool> est_used(est.size(), false);
  std::vector<PoseMatch> matches;
  for (const PoseMatch& c : candidates) {
    if (gt_used[c.gt_index] || est_used[c.est_index]) continue;
    gt_used[c.gt_index] = true;
    est_used[c.est_index] = true;
    matches.push_back(c);
  }
  std::sort(matches.begin(), matches.end(), [&](const PoseMatch& a, const PoseMatch& b) {
    return std::make_tuple(gt[a.gt_index].timestamp_s, a.gt_index) <
           std::make_tuple(gt[b.gt_index].timestamp_s, b.gt_index);
  });
  return matches;
}

AteResult evaluate_ate(const std::vector<StampedPose>& gt, const std::vector<StampedPose>& est,
                       const AteParams& params) {
  params.validate();
  if (gt.empty()) fail(ErrorCode::InvalidData, "ATE: the ground-truth trajectory has no poses");
  if (est.empty()) fail(ErrorCode::InvalidData, "ATE: the estimated trajectory has no poses");
  check_finite(gt, "ground-truth", true);
  check_finite(est, "estimated", true);

  AteResult r;
  r.matches = associate_by_time(gt, est, params.max_dt_s);
  r.matched = r.matches.size();
  if (r.matched < kMinMatches)
    fail(ErrorCode::InvalidData,
         "ATE: only {} of {} estimated poses have a ground-truth pose within max_dt {} s (need at "
         "least {}); do both trajectories use the same clock?",
         r.matched, est.size(), params.max_dt_s, kMinMatches);

  const auto n = static_cast<Eigen::Index>(r.matched);
  Eigen::Matrix3Xd p_gt(3, n);
  Eigen::Matrix3Xd p_est(3, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const PoseMatch& m = r.matches[static_cast<std::size_t>(i)];
    p_gt.col(i) = gt[m.gt_index].T_wc.translation();
    p_est.col(i) = est[m.est_index].T_wc.translation();
  }
  if (params.align) r.T_gt_est = rigid_alignment(p_est, p_gt);

  r.errors_m.resize(r.matched);
  double sum = 0, sum_sq = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    const double e = (r.T_gt_est * p_est.col(i) - p_gt.col(i)).norm();
    r.errors_m[static_cast<std::size_t>(i)] = e;
    sum += e;
    sum_sq += e * e;
  }
  const auto count = static_cast<double>(r.matched);
  r.rmse_m = std::sqrt(sum_sq / count);
  r.mean_m = sum / count;
  double var = 0;
  for (const double e : r.errors_m) var += (e - r.mean_m) * (e - r.mean_m);
  r.std_m = std::sqrt(var / count);
  r.median_m = median_of(r.errors_m);
  const auto [lo, hi] = std::minmax_element(r.errors_m.begin(), r.errors_m.end());
  r.min_m = *lo;
  r.max_m = *hi;
  return r;
}

}  // namespace hivox

#pragma once
// Gauss-Newton on the point-to-plane normal equations and the verdict on an alignment: host code
// written once for every device, stepping the shared state machine of track/gauss_newton.h. Only
// the ICP reduction (the sums over a pyramid level's pixels) is device-specific; the CPU tracker
// and the CUDA loop hand theirs in.

#include <cstdint>
#include <functional>

#include <Eigen/Core>

#include "hivox/core/pose.h"
#include "hivox/track/params.h"
#include "hivox/track/tracker.h"
#include "track/gauss_newton.h"

namespace hivox::icp {

/// One Gauss-Newton pass's sums in the reductions' layout (track/gauss_newton.h): the upper
/// triangle of A row-major (21), b (6), the inliers' squared residuals, their distances from the
/// camera, their count.
struct Sums {
  double v[kernels::kIcpSums] = {};

  /// Adds partial sums: A's upper triangle (21), b (6), and the residual statistics.
  template <typename T>
  void add(const T* A_upper, const T* b6, double r2, double distance, int64_t inliers) {
    for (int k = 0; k < kernels::kIcpB; ++k) v[k] += A_upper[k];
    for (int i = 0; i < 6; ++i) v[kernels::kIcpB + i] += b6[i];
    v[kernels::kIcpR2] += r2;
    v[kernels::kIcpDistance] += distance;
    v[kernels::kIcpInliers] += static_cast<double>(inliers);
  }
};

/// A pass's sums as the verdict reads them: the normal equations (6x6, the motion about the
/// camera centre) and the residual statistics of its pairs.
struct System {
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
  double r2 = 0;        ///< sum of squared (unweighted) residuals of the inliers
  double distance = 0;  ///< sum of the inliers' distances from the camera centre
  int64_t inliers = 0;

  static System from_sums(const double* sums);
};

/// One pass over pyramid level `level` (0 finest) at pose `T_wc`.
using Reduce = std::function<Sums(int level, const Pose& T_wc)>;

/// Aligns from `T_wc_init` (Gauss-Newton on SE(3), coarsest level first, `params.iterations`
/// passes per level at most) and judges the result: the finest level's numbers and the quality;
/// a lost frame keeps the start pose. `valid_pixels`: finest-level pixels with a point and a
/// normal. Fills everything but the timings.
void align_and_judge(const TrackParams& params, const Reduce& reduce, int64_t valid_pixels,
                     const Pose& T_wc_init, TrackResult* result);

kernels::PoseD to_posed(const Pose& T);
Pose from_posed(const kernels::PoseD& p);

/// Where Gauss-Newton ended: the pose, the finest level's last system and the pose it was built
/// at, the increments applied, and whether a step diverged.
struct Alignment {
  Pose T = Pose::Identity();
  Pose T_fin = Pose::Identity();
  System fin;
  int iterations = 0;
  bool diverged = false;
};
/// align_and_judge's alignment alone: Gauss-Newton through the shared state machine
/// (kernels::icp_update), one `reduce` pass at a time.
Alignment align(const TrackParams& params, const Reduce& reduce, const Pose& T_wc_init);

/// The alignment a run of the shared state machine ended in, on whichever device stepped it.
Alignment alignment_of(const kernels::IcpState& s);

/// align_and_judge's verdict for an alignment made elsewhere (a device that stepped the state
/// machine itself); `reduce` serves the fresh finest-level pass taken when the last increment
/// was large.
void judge_alignment(const TrackParams& params, Alignment a, const Reduce& reduce,
                     int64_t valid_pixels, const Pose& T_wc_init, TrackResult* result);

}  // namespace hivox::icp

#include "track/icp_solver.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

namespace hivox::icp {

System System::from_sums(const double* sums) {
  System s;
  int k = 0;
  for (int i = 0; i < 6; ++i) {
    for (int j = i; j < 6; ++j) s.A(i, j) = sums[k++];
    s.b(i) = sums[kernels::kIcpB + i];
  }
  s.A.triangularView<Eigen::StrictlyLower>() = s.A.transpose();
  s.r2 = sums[kernels::kIcpR2];
  s.distance = sums[kernels::kIcpDistance];
  s.inliers = static_cast<int64_t>(sums[kernels::kIcpInliers]);
  return s;
}

kernels::PoseD to_posed(const Pose& T) {
  kernels::PoseD p;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) p.R[3 * i + j] = T.linear()(i, j);
    p.t[i] = T.translation()(i);
  }
  return p;
}

Pose from_posed(const kernels::PoseD& p) {
  Pose T = Pose::Identity();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) T.linear()(i, j) = p.R[3 * i + j];
    T.translation()(i) = p.t[i];
  }
  return T;
}

Alignment alignment_of(const kernels::IcpState& s) {
  Alignment a;
  a.T = from_posed(s.T);
  a.T_fin = from_posed(s.T_fin);
  a.fin = System::from_sums(s.fin);
  a.iterations = s.iterations;
  a.diverged = s.diverged != 0;
  return a;
}

namespace {

double rotation_deg(const Pose& T) {
  return rotation_angle_rad(T) * 180.0 / std::numbers::pi;
}

void judge(const TrackParams& params, const Alignment& a, int64_t valid_pixels,
           const Pose& T_wc_init, TrackResult* result) {
  const System& fin = a.fin;
  const Pose& T = a.T;
  result->valid_pixels = valid_pixels;
  result->inliers = fin.inliers;
  result->inlier_ratio =
      result->valid_pixels > 0 ? static_cast<double>(fin.inliers) / result->valid_pixels : 0.0;
  result->rms_m = fin.inliers > 0 ? std::sqrt(fin.r2 / static_cast<double>(fin.inliers)) : 0.0;
  if (fin.inliers >= 6) {
    // Rotations scaled by the mean lever arm so that both halves are in metres.
    const double arm = std::max(1e-3, fin.distance / static_cast<double>(fin.inliers));
    Eigen::Matrix<double, 6, 1> s;
    s << 1, 1, 1, 1 / arm, 1 / arm, 1 / arm;
    const Eigen::Matrix<double, 6, 6> An = s.asDiagonal() * fin.A * s.asDiagonal();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(An,
                                                                         Eigen::EigenvaluesOnly);
    const double lmax = eig.eigenvalues().maxCoeff();
    result->condition = lmax > 0.0 ? std::max(0.0, eig.eigenvalues().minCoeff()) / lmax : 0.0;
  }

  const Pose jump = T_wc_init.inverse() * T;
  const bool lost =
      a.diverged || !T.matrix().allFinite() || fin.inliers < 6 ||
      result->inlier_ratio < params.lost_inlier_ratio || result->rms_m > params.lost_rms_m ||
      jump.translation().norm() > params.lost_jump_m || rotation_deg(jump) > params.lost_jump_deg;
  if (lost) {
    result->quality = TrackingQuality::Lost;
    result->T_wc = T_wc_init;
  } else {
    result->quality =
        result->inlier_ratio < params.poor_inlier_ratio || result->condition < params.poor_condition
            ? TrackingQuality::Poor
            : TrackingQuality::Good;
    result->T_wc = T;
  }
}

}  // namespace

Alignment align(const TrackParams& params, const Reduce& reduce, const Pose& T_wc_init) {
  kernels::IcpState s = kernels::icp_start(to_posed(T_wc_init));
  for (int level = params.levels() - 1; level >= 0 && s.diverged == 0; --level)
    for (int it = 0; it < params.iterations[static_cast<std::size_t>(level)]; ++it) {
      if (kernels::icp_skips(s, level)) break;
      kernels::icp_update(s, reduce(level, from_posed(s.T)).v, level, params.convergence_step);
    }
  return alignment_of(s);
}

void align_and_judge(const TrackParams& params, const Reduce& reduce, int64_t valid_pixels,
                     const Pose& T_wc_init, TrackResult* result) {
  judge_alignment(params, align(params, reduce, T_wc_init), reduce, valid_pixels, T_wc_init,
                  result);
}

void judge_alignment(const TrackParams& params, Alignment a, const Reduce& reduce,
                     int64_t valid_pixels, const Pose& T_wc_init, TrackResult* result) {
  result->iterations = a.iterations;
  // The verdict, from the correspondences on the finest level at the pose of its last pass
  // (one increment before the end: the same correspondences once converged); a fresh pass only
  // when the last increment was large.
  const Pose last_step = a.T_fin.inverse() * a.T;
  if (a.iterations == 0 || last_step.translation().norm() > 1e-3 || rotation_deg(last_step) > 0.1)
    a.fin = System::from_sums(reduce(0, a.T).v);
  judge(params, a, valid_pixels, T_wc_init, result);
}

}  // namespace hivox::icp

#include "track/icp_solver.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

namespace hivox::icp {

void System::symmetrize() {
  A.triangularView<Eigen::StrictlyLower>() = A.transpose();
}

namespace {

/// Pose after the world-frame motion (t, w) of the camera about its centre c:
/// p -> R(w) (p - c) + c + t.
Pose apply_increment(const Pose& T, const Eigen::Matrix<double, 6, 1>& x) {
  const Eigen::Vector3d t = x.head<3>(), w = x.tail<3>();
  const double angle = w.norm();
  const Eigen::Matrix3d R = angle > 0.0 ? Eigen::AngleAxisd(angle, w / angle).toRotationMatrix()
                                        : Eigen::Matrix3d::Identity();
  const Eigen::Vector3d c = T.translation();
  Pose inc = Pose::Identity();
  inc.linear() = R;
  inc.translation() = c + t - R * c;
  Pose out = inc * T;
  // Keep the rotation orthonormal over many small updates.
  out.linear() = Eigen::Quaterniond(out.linear()).normalized().toRotationMatrix();
  return out;
}

double rotation_deg(const Pose& T) {
  return rotation_angle_rad(T) * 180.0 / std::numbers::pi;
}

/// Where Gauss-Newton ended: the pose, the finest level's last system and the pose it was built
/// at, the iterations run, and whether a step diverged.
struct Alignment {
  Pose T = Pose::Identity();
  Pose T_fin = Pose::Identity();
  System fin;
  int iterations = 0;
  bool diverged = false;
};

Alignment align(const TrackParams& params, const Reduce& reduce, const Pose& T_wc_init) {
  Alignment a;
  Pose T = T_wc_init;
  a.T_fin = T;
  for (int level = params.levels() - 1; level >= 0 && !a.diverged; --level) {
    for (int it = 0; it < params.iterations[static_cast<std::size_t>(level)]; ++it) {
      const System ne = reduce(level, T);
      if (level == 0) {
        a.fin = ne;
        a.T_fin = T;
      }
      if (ne.inliers < 6) break;
      const Eigen::Matrix<double, 6, 1> x = ne.A.ldlt().solve(-ne.b);
      if (!x.allFinite()) {
        a.diverged = true;
        break;
      }
      T = apply_increment(T, x);
      ++a.iterations;
      if (x.head<3>().norm() < params.convergence_step &&
          x.tail<3>().norm() < params.convergence_step)
        break;
    }
  }
  a.T = T;
  return a;
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

void align_and_judge(const TrackParams& params, const Reduce& reduce, int64_t valid_pixels,
                     const Pose& T_wc_init, TrackResult* result) {
  Alignment a = align(params, reduce, T_wc_init);
  result->iterations = a.iterations;
  // The verdict, from the correspondences on the finest level at the pose of its last pass
  // (one increment before the end: the same correspondences once converged); a fresh pass only
  // when the last increment was large.
  const Pose last_step = a.T_fin.inverse() * a.T;
  if (a.iterations == 0 || last_step.translation().norm() > 1e-3 || rotation_deg(last_step) > 0.1)
    a.fin = reduce(0, a.T);
  judge(params, a, valid_pixels, T_wc_init, result);
}

}  // namespace hivox::icp

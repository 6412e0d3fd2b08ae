#pragma once
// Gauss-Newton on the point-to-plane normal equations, written once for every device: the 6x6
// solve, the pose increment and the per-pass state machine (when a level's passes stop, when the
// alignment has diverged). The CPU tracker steps it on the host after each reduction; a device
// can step it where its reduction ends, with the pose kept in device memory between passes.
//
// Sums come in the reductions' layout (kIcpSums doubles): the upper triangle of A row-major
// (21), b (6), the inliers' squared residuals, their distances from the camera, their count.

#include <cmath>
#include <cstdint>

#include "hivox/core/hd.h"
#include "hivox/core/math.h"

namespace hivox::kernels {

inline constexpr int kIcpSums = 30;
inline constexpr int kIcpB = 21;
inline constexpr int kIcpR2 = 27;
inline constexpr int kIcpDistance = 28;
inline constexpr int kIcpInliers = 29;

/// A rigid pose in double precision: x -> R x + t, R row-major.
struct PoseD {
  double R[9];
  double t[3];
};

/// `p` in single precision, as the per-pixel kernels take a pose.
HIVOX_HD inline Rigid3f rigid3f_of(const PoseD& p) {
  Rigid3f r;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r.R(i, j) = static_cast<float>(p.R[3 * i + j]);
    r.t[i] = static_cast<float>(p.t[i]);
  }
  return r;
}

/// Solves A x = b for the symmetric 6x6 `A` given by its upper triangle (row-major, 21 values):
/// LDL^T with symmetric pivoting on the largest remaining diagonal; a pivot of magnitude below
/// the smallest normal double solves its component as 0 (a semidefinite system gets the
/// solution of its well-defined part). Returns false when x is not finite.
HIVOX_HD inline bool solve_ldlt6(const double* A_upper, const double* b, double x[6]) {
  double L[6][6];
  int k = 0;
  for (int i = 0; i < 6; ++i)
    for (int j = i; j < 6; ++j) L[i][j] = L[j][i] = A_upper[k++];
  int perm[6] = {0, 1, 2, 3, 4, 5};
  // In place: the strict lower triangle becomes L, the diagonal D.
  for (int c = 0; c < 6; ++c) {
    int p = c;
    for (int i = c + 1; i < 6; ++i)
      if (std::fabs(L[i][i]) > std::fabs(L[p][p])) p = i;
    if (p != c) {
      for (int j = 0; j < 6; ++j) {  // swap rows c and p, then columns
        const double r = L[c][j];
        L[c][j] = L[p][j];
        L[p][j] = r;
      }
      for (int i = 0; i < 6; ++i) {
        const double r = L[i][c];
        L[i][c] = L[i][p];
        L[i][p] = r;
      }
      const int q = perm[c];
      perm[c] = perm[p];
      perm[p] = q;
    }
    double d = L[c][c];
    for (int j = 0; j < c; ++j) d -= L[c][j] * L[c][j] * L[j][j];
    L[c][c] = d;
    for (int i = c + 1; i < 6; ++i) {
      double v = L[i][c];
      for (int j = 0; j < c; ++j) v -= L[i][j] * L[c][j] * L[j][j];
      L[i][c] = d != 0.0 ? v / d : v;
    }
  }
  double y[6];
  for (int i = 0; i < 6; ++i) {
    double v = b[perm[i]];
    for (int j = 0; j < i; ++j) v -= L[i][j] * y[j];
    y[i] = v;
  }
  constexpr double kTiny = 2.2250738585072014e-308;  // the smallest normal double
  for (int i = 0; i < 6; ++i) y[i] = std::fabs(L[i][i]) > kTiny ? y[i] / L[i][i] : 0.0;
  for (int i = 5; i >= 0; --i) {
    double v = y[i];
    for (int j = i + 1; j < 6; ++j) v -= L[j][i] * y[j];
    y[i] = v;
  }
  bool finite = true;
  for (int i = 0; i < 6; ++i) {
    x[perm[i]] = y[i];
    finite = finite && std::isfinite(y[i]);
  }
  return finite;
}

/// R with its drift from a rotation removed: through the unit quaternion nearest to it
/// (the largest of w, x, y, z computed from the diagonal first, for accuracy).
HIVOX_HD inline void orthonormalize(double R[9]) {
  auto m = [&](int i, int j) { return R[3 * i + j]; };
  double q[4];  // x, y, z, w
  const double trace = m(0, 0) + m(1, 1) + m(2, 2);
  if (trace > 0.0) {
    double s = std::sqrt(trace + 1.0);
    q[3] = 0.5 * s;
    s = 0.5 / s;
    q[0] = (m(2, 1) - m(1, 2)) * s;
    q[1] = (m(0, 2) - m(2, 0)) * s;
    q[2] = (m(1, 0) - m(0, 1)) * s;
  } else {
    int i = 0;
    if (m(1, 1) > m(0, 0)) i = 1;
    if (m(2, 2) > m(i, i)) i = 2;
    const int j = (i + 1) % 3, k = (j + 1) % 3;
    double s = std::sqrt(m(i, i) - m(j, j) - m(k, k) + 1.0);
    q[i] = 0.5 * s;
    s = 0.5 / s;
    q[3] = (m(k, j) - m(j, k)) * s;
    q[j] = (m(j, i) + m(i, j)) * s;
    q[k] = (m(k, i) + m(i, k)) * s;
  }
  const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  const double x = q[0] / n, y = q[1] / n, z = q[2] / n, w = q[3] / n;
  const double tx = 2 * x, ty = 2 * y, tz = 2 * z;
  const double twx = tx * w, twy = ty * w, twz = tz * w;
  const double txx = tx * x, txy = ty * x, txz = tz * x;
  const double tyy = ty * y, tyz = tz * y, tzz = tz * z;
  R[0] = 1 - (tyy + tzz);
  R[1] = txy - twz;
  R[2] = txz + twy;
  R[3] = txy + twz;
  R[4] = 1 - (txx + tzz);
  R[5] = tyz - twx;
  R[6] = txz - twy;
  R[7] = tyz + twx;
  R[8] = 1 - (txx + tyy);
}

/// The pose after the world-frame motion x = (t, w) of the camera about its centre c:
/// p -> R(w) (p - c) + c + t, with R(w) the rotation by |w| about w / |w| (Rodrigues); the
/// result's rotation orthonormalised.
HIVOX_HD inline PoseD apply_increment(const PoseD& T, const double x[6]) {
  const double w[3] = {x[3], x[4], x[5]};
  const double angle = std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
  double R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  if (angle > 0.0) {
    const double a[3] = {w[0] / angle, w[1] / angle, w[2] / angle};
    const double s = std::sin(angle), c = std::cos(angle);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) R[3 * i + j] = (1 - c) * a[i] * a[j];
    for (int i = 0; i < 3; ++i) R[4 * i] += c;
    R[1] -= s * a[2];
    R[3] += s * a[2];
    R[2] += s * a[1];
    R[6] -= s * a[1];
    R[5] -= s * a[0];
    R[7] += s * a[0];
  }
  // The increment: rotation R, translation c + t - R c; applied before T (world frame).
  const double* c = T.t;
  double inc_t[3];
  for (int i = 0; i < 3; ++i)
    inc_t[i] = c[i] + x[i] - (R[3 * i] * c[0] + R[3 * i + 1] * c[1] + R[3 * i + 2] * c[2]);
  PoseD out;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j)
      out.R[3 * i + j] = R[3 * i] * T.R[j] + R[3 * i + 1] * T.R[3 + j] + R[3 * i + 2] * T.R[6 + j];
    out.t[i] = R[3 * i] * T.t[0] + R[3 * i + 1] * T.t[1] + R[3 * i + 2] * T.t[2] + inc_t[i];
  }
  orthonormalize(out.R);
  return out;
}

/// Gauss-Newton between passes: the pose, and what the verdict reads afterwards.
struct IcpState {
  PoseD T;                  ///< the pose being refined
  PoseD T_fin;              ///< the pose the finest level's last sums were taken at
  double fin[kIcpSums];     ///< the finest level's last sums (zeros before its first)
  int32_t iterations = 0;   ///< increments applied
  int32_t done_level = -1;  ///< a level whose passes have stopped (converged, too few pairs)
  int32_t diverged = 0;     ///< a step was not finite: every later pass is skipped
};

HIVOX_HD inline IcpState icp_start(const PoseD& T) {
  IcpState s;
  s.T = T;
  s.T_fin = T;
  for (int k = 0; k < kIcpSums; ++k) s.fin[k] = 0.0;
  return s;
}

/// Whether a pass at `level` is skipped (the level has stopped, or the alignment diverged).
HIVOX_HD inline bool icp_skips(const IcpState& s, int level) {
  return s.diverged != 0 || s.done_level == level;
}

/// One pass's update from its sums at `level` (0 finest): the increment applied, the level
/// stopped when it has fewer than 6 pairs or both halves of the step are below
/// `convergence_step`, the alignment marked diverged when the step is not finite.
HIVOX_HD inline void icp_update(IcpState& s, const double* sums, int level,
                                double convergence_step) {
  if (level == 0) {
    for (int k = 0; k < kIcpSums; ++k) s.fin[k] = sums[k];
    s.T_fin = s.T;
  }
  if (sums[kIcpInliers] < 6.0) {
    s.done_level = level;
    return;
  }
  double minus_b[6], x[6];
  for (int i = 0; i < 6; ++i) minus_b[i] = -sums[kIcpB + i];
  if (!solve_ldlt6(sums, minus_b, x)) {
    s.diverged = 1;
    return;
  }
  s.T = apply_increment(s.T, x);
  ++s.iterations;
  const double step_t = std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
  const double step_w = std::sqrt(x[3] * x[3] + x[4] * x[4] + x[5] * x[5]);
  if (step_t < convergence_step && step_w < convergence_step) s.done_level = level;
}

}  // namespace hivox::kernels

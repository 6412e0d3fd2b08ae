// Gauss-Newton's shared steps (track/gauss_newton.h) against Eigen: the pivoted 6x6 LDL^T solve
// (also on singular systems), the pose increment, the orthonormalisation, and the per-pass state
// machine the CPU tracker and the CUDA loop step.

#include "track/gauss_newton.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

namespace hivox {
namespace {

using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;

void upper_of(const Mat6& A, double* out) {
  int k = 0;
  for (int i = 0; i < 6; ++i)
    for (int j = i; j < 6; ++j) out[k++] = A(i, j);
}

/// J^T J over `rows` random rows, `null_dims` columns of J zero at random places (a
/// rank-deficient system when > 0), with column scales spread over `spread` decades in a random
/// order (so that the pivoting has work to do).
Mat6 normal_matrix(std::mt19937& rng, int rows, int null_dims, double spread) {
  std::normal_distribution<double> g;
  int order[6] = {0, 1, 2, 3, 4, 5};
  std::shuffle(order, order + 6, rng);
  Mat6 A = Mat6::Zero();
  for (int r = 0; r < rows; ++r) {
    Vec6 j;
    for (int c = 0; c < 6; ++c)
      j(order[c]) = c < 6 - null_dims ? g(rng) * std::pow(10.0, -spread * c / 5.0) : 0.0;
    A += j * j.transpose();
  }
  return A;
}

TEST(GaussNewton, SolvesAsEigensLdltDoes) {
  std::mt19937 rng(7);
  std::normal_distribution<double> g;
  for (const int null_dims : {0, 1, 3, 6})
    for (const double spread : {0.0, 3.0, 6.0})
      for (int trial = 0; trial < 20; ++trial) {
        SCOPED_TRACE(testing::Message() << null_dims << " null dims, spread " << spread);
        const Mat6 A = normal_matrix(rng, 40, null_dims, spread);
        Vec6 b;
        for (int c = 0; c < 6; ++c) b(c) = g(rng);
        // A consistent right side for a singular A (as J^T r always is).
        if (null_dims > 0) b = A * b;
        double upper[21], x[6];
        upper_of(A, upper);
        ASSERT_TRUE(kernels::solve_ldlt6(upper, b.data(), x));
        const Vec6 ref = A.ldlt().solve(b);
        const Vec6 got = Eigen::Map<const Vec6>(x);
        EXPECT_LE((got - ref).norm(), 1e-8 * (1.0 + ref.norm()))
            << "got " << got.transpose() << "\nref " << ref.transpose();
        // A solution of the system where one exists.
        EXPECT_LE((A * got - b).norm(), 1e-8 * (1.0 + b.norm()));
      }
}

TEST(GaussNewton, ANonFiniteSystemIsReported) {
  double upper[21] = {};
  upper[0] = 1;
  upper[6] = 1;
  upper[11] = 1;
  upper[15] = 1;
  upper[18] = 1;
  upper[20] = 1;  // the identity
  double b[6] = {1, 2, 3, 4, 5, 6}, x[6];
  ASSERT_TRUE(kernels::solve_ldlt6(upper, b, x));
  for (int i = 0; i < 6; ++i) EXPECT_DOUBLE_EQ(x[i], b[i]);
  b[2] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(kernels::solve_ldlt6(upper, b, x));
  b[2] = 3;
  upper[11] = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(kernels::solve_ldlt6(upper, b, x));
}

kernels::PoseD pose_of(const Eigen::Isometry3d& T) {
  kernels::PoseD p;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) p.R[3 * i + j] = T.linear()(i, j);
    p.t[i] = T.translation()(i);
  }
  return p;
}

TEST(GaussNewton, IncrementsThePoseAboutTheCameraCentre) {
  std::mt19937 rng(3);
  std::normal_distribution<double> g;
  for (int trial = 0; trial < 100; ++trial) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(3 * g(rng), Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized())
                     .toRotationMatrix();
    T.translation() = Eigen::Vector3d(g(rng), g(rng), g(rng));
    // Steps from tiny to a large rotation (past 90 degrees).
    const double scale = std::pow(10.0, -6.0 + 6.0 * trial / 99.0);
    Vec6 x;
    for (int c = 0; c < 6; ++c) x(c) = scale * g(rng);
    // Reference: p -> R(w) (p - c) + c + t applied after T.
    const Eigen::Vector3d w = x.tail<3>(), c = T.translation();
    const Eigen::Matrix3d R = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
    Eigen::Isometry3d inc = Eigen::Isometry3d::Identity();
    inc.linear() = R;
    inc.translation() = c + x.head<3>() - R * c;
    const Eigen::Isometry3d ref = inc * T;
    const kernels::PoseD got = kernels::apply_increment(pose_of(T), x.data());
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(got.t[i], ref.translation()(i), 1e-12);
      for (int j = 0; j < 3; ++j) EXPECT_NEAR(got.R[3 * i + j], ref.linear()(i, j), 1e-12);
    }
    const Eigen::Matrix3d Rg =
        Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(got.R);
    EXPECT_LE((Rg * Rg.transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-14);
    EXPECT_GT(Rg.determinant(), 0.0);
  }
  // A zero step changes nothing.
  const Eigen::Isometry3d T(Eigen::Translation3d(1, 2, 3) *
                            Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()));
  const double zero[6] = {};
  const kernels::PoseD same = kernels::apply_increment(pose_of(T), zero);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(same.t[i], T.translation()(i), 1e-15);
}

TEST(GaussNewton, OrthonormalisesAsTheNearestQuaternionDoes) {
  // Every branch: trace > 0, and each of x, y, z the largest diagonal (rotations near 180
  // degrees about each axis), each perturbed.
  std::mt19937 rng(11);
  std::normal_distribution<double> g;
  const Eigen::Vector3d axes[4] = {{0.2, 0.1, 1.0}, {1, 0.1, 0.05}, {0.1, 1, 0.05}, {0.05, 0.1, 1}};
  const double angles[4] = {0.5, 3.1, 3.1, 3.1};
  for (int k = 0; k < 4; ++k) {
    Eigen::Matrix3d R = Eigen::AngleAxisd(angles[k], axes[k].normalized()).toRotationMatrix();
    for (int i = 0; i < 9; ++i) R.data()[i] += 1e-7 * g(rng);
    const Eigen::Matrix3d ref = Eigen::Quaterniond(R).normalized().toRotationMatrix();
    double m[9];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) m[3 * i + j] = R(i, j);
    kernels::orthonormalize(m);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) EXPECT_NEAR(m[3 * i + j], ref(i, j), 1e-14) << "case " << k;
  }
}

/// Sums (the reductions' layout) of the system A x = -b with inliers `n`.
void sums_of(const Mat6& A, const Vec6& b, double n, double* sums) {
  upper_of(A, sums);
  for (int i = 0; i < 6; ++i) sums[kernels::kIcpB + i] = b(i);
  sums[kernels::kIcpR2] = 1;
  sums[kernels::kIcpDistance] = 2;
  sums[kernels::kIcpInliers] = n;
}

TEST(GaussNewton, StateMachineStopsLevelsAndRecordsTheFinestPass) {
  kernels::PoseD start = {{1, 0, 0, 0, 1, 0, 0, 0, 1}, {0, 0, 0}};
  kernels::IcpState s = kernels::icp_start(start);
  EXPECT_FALSE(kernels::icp_skips(s, 2));
  double sums[kernels::kIcpSums];
  const Mat6 I = Mat6::Identity();
  // A step of 0.01 m along x at the coarsest level: applied, the level goes on.
  Vec6 b = Vec6::Zero();
  b(0) = -0.01;
  sums_of(I, b, 100, sums);
  kernels::icp_update(s, sums, 2, 1e-4);
  EXPECT_EQ(s.iterations, 1);
  EXPECT_NEAR(s.T.t[0], 0.01, 1e-15);
  EXPECT_FALSE(kernels::icp_skips(s, 2));
  EXPECT_EQ(s.fin[kernels::kIcpInliers], 0) << "only the finest level's sums are kept";
  // Too few pairs: the level stops without a step; the next level runs.
  sums_of(I, b, 5, sums);
  kernels::icp_update(s, sums, 2, 1e-4);
  EXPECT_EQ(s.iterations, 1);
  EXPECT_TRUE(kernels::icp_skips(s, 2));
  EXPECT_FALSE(kernels::icp_skips(s, 1));
  // A step below the convergence threshold stops its level after applying it.
  b(0) = -1e-5;
  sums_of(I, b, 100, sums);
  kernels::icp_update(s, sums, 1, 1e-4);
  EXPECT_EQ(s.iterations, 2);
  EXPECT_TRUE(kernels::icp_skips(s, 1));
  // The finest level records its sums and the pose they were taken at, before its step.
  b(0) = -0.001;
  sums_of(I, b, 100, sums);
  const double before = s.T.t[0];
  kernels::icp_update(s, sums, 0, 1e-4);
  EXPECT_EQ(s.T_fin.t[0], before);
  EXPECT_EQ(s.fin[kernels::kIcpInliers], 100);
  EXPECT_NEAR(s.T.t[0], before + 0.001, 1e-15);
  // A non-finite step: diverged, and every later pass is skipped.
  sums[kernels::kIcpB] = std::numeric_limits<double>::quiet_NaN();
  kernels::icp_update(s, sums, 0, 1e-4);
  EXPECT_EQ(s.diverged, 1);
  EXPECT_EQ(s.iterations, 3);
  EXPECT_TRUE(kernels::icp_skips(s, 0));
}

}  // namespace
}  // namespace hivox

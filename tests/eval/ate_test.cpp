// Absolute trajectory error: association by timestamp (TUM's associate.py rule), rigid
// alignment, and error statistics, on trajectories whose ATE is known analytically.

#include "hivox/eval/trajectory_eval.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>

#include "eval/trajectory_test_util.h"
#include "hivox/core/error.h"
#include "test_util.h"

namespace hivox {
namespace {

using test::loop_trajectory;
using test::perturbed;
using test::some_rigid_motion;

using test::contains;
using test::error_of;

StampedPose at(double t_s, const Eigen::Vector3d& p_w) {
  StampedPose p;
  p.timestamp_s = t_s;
  p.T_wc.translation() = p_w;
  return p;
}

// Sum of squared errors of `est` moved by `T` against `gt`, over the result's matches.
double sum_sq_error(const std::vector<StampedPose>& gt, const std::vector<StampedPose>& est,
                    const AteResult& r, const Pose& T) {
  double s = 0;
  for (const PoseMatch& m : r.matches)
    s +=
        (T * est[m.est_index].T_wc.translation() - gt[m.gt_index].T_wc.translation()).squaredNorm();
  return s;
}

TEST(Ate, IdenticalTrajectoriesGiveZero) {
  const auto gt = loop_trajectory(100);
  for (const bool align : {true, false}) {
    const AteResult r = evaluate_ate(gt, gt, {.align = align});
    EXPECT_EQ(r.matched, 100u);
    ASSERT_EQ(r.errors_m.size(), 100u);
    EXPECT_LT(r.rmse_m, 1e-12) << "align " << align;
    EXPECT_LT(r.max_m, 1e-12);
    EXPECT_TRUE(r.T_gt_est.matrix().isIdentity(1e-12)) << r.T_gt_est.matrix();
    for (const PoseMatch& m : r.matches) {
      EXPECT_EQ(m.gt_index, m.est_index);
      EXPECT_EQ(m.dt_s, 0.0);
    }
  }
}

TEST(Ate, RigidTransformIsAlignedAway) {
  const auto gt = loop_trajectory(100);
  const Pose T = some_rigid_motion();
  const auto est = perturbed(gt, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), T);

  const AteResult aligned = evaluate_ate(gt, est);
  EXPECT_EQ(aligned.matched, 100u);
  EXPECT_LT(aligned.rmse_m, 1e-9);
  EXPECT_LT(aligned.max_m, 1e-9);
  // The alignment found is the inverse of the motion applied.
  EXPECT_TRUE(aligned.T_gt_est.isApprox(T.inverse(), 1e-9)) << aligned.T_gt_est.matrix();

  // Without alignment each error is how far T moves that position.
  const AteResult raw = evaluate_ate(gt, est, {.align = false});
  EXPECT_TRUE(raw.T_gt_est.matrix().isIdentity(0.0));
  ASSERT_EQ(raw.errors_m.size(), 100u);
  double sum_sq = 0;
  for (std::size_t i = 0; i < raw.errors_m.size(); ++i) {
    const Eigen::Vector3d p = gt[raw.matches[i].gt_index].T_wc.translation();
    const double expected = (T * p - p).norm();
    EXPECT_NEAR(raw.errors_m[i], expected, 1e-12) << i;
    sum_sq += expected * expected;
  }
  EXPECT_NEAR(raw.rmse_m, std::sqrt(sum_sq / 100.0), 1e-12);
  EXPECT_GT(raw.rmse_m, 1.0);
}

// A mirror image is not a rigid motion: the alignment must stay a rotation (det +1) and leave an
// error, where an unconstrained orthogonal fit would reflect the estimate back onto the truth.
TEST(Ate, MirroredTrajectoryIsNotReflectedAway) {
  const auto gt = loop_trajectory(100);
  auto est = gt;
  for (auto& p : est) p.T_wc.translation().x() *= -1.0;
  const AteResult r = evaluate_ate(gt, est);
  EXPECT_NEAR(r.T_gt_est.linear().determinant(), 1.0, 1e-12);
  EXPECT_TRUE((r.T_gt_est.linear().transpose() * r.T_gt_est.linear()).isIdentity(1e-12));
  EXPECT_GT(r.rmse_m, 0.1);
}

// Offsets of +-v1 and +-v2 that alignment cannot remove (zero mean, no correlation with the
// positions; see trajectory_test_util.h): errors are exactly |v1| on half the poses and |v2| on
// the other half, with or without a rigid motion applied on top.
TEST(Ate, ZeroMeanPerturbationGivesItsKnownRmse) {
  const auto gt = loop_trajectory(120);
  const Eigen::Vector3d v1(0.01, 0.0, 0.0);   // 1 cm
  const Eigen::Vector3d v2(0.0, 0.02, 0.02);  // 2.83 cm
  const double e1 = v1.norm(), e2 = v2.norm();
  const double rmse = std::sqrt((e1 * e1 + e2 * e2) / 2.0);
  const double mean = (e1 + e2) / 2.0;

  for (const Pose& T : {Pose(Pose::Identity()), some_rigid_motion()}) {
    const auto est = perturbed(gt, v1, v2, T);
    const AteResult r = evaluate_ate(gt, est);
    ASSERT_EQ(r.matched, 120u);
    EXPECT_NEAR(r.rmse_m, rmse, 1e-12);
    EXPECT_NEAR(r.mean_m, mean, 1e-12);
    EXPECT_NEAR(r.median_m, mean, 1e-12);  // even count: mean of the two middle values
    EXPECT_NEAR(r.std_m, (e2 - e1) / 2.0, 1e-12);
    EXPECT_NEAR(r.min_m, e1, 1e-12);
    EXPECT_NEAR(r.max_m, e2, 1e-12);
    for (std::size_t i = 0; i < r.errors_m.size(); ++i)
      EXPECT_NEAR(r.errors_m[i], r.matches[i].est_index % 4 < 2 ? e1 : e2, 1e-12) << i;
    EXPECT_TRUE(r.T_gt_est.isApprox(T.inverse(), 1e-12)) << r.T_gt_est.matrix();

    // The claim that nothing better exists, checked directly: nudging the alignment found in
    // any direction (rotation about each axis, shift along each axis) only increases the error.
    const double best = sum_sq_error(gt, est, r, r.T_gt_est);
    EXPECT_NEAR(best, 120.0 * rmse * rmse, 1e-12);
    for (int axis = 0; axis < 3; ++axis) {
      for (const double step : {-1e-3, 1e-3}) {
        Pose nudge = Pose::Identity();
        nudge.linear() = Eigen::AngleAxisd(step, Eigen::Vector3d::Unit(axis)).toRotationMatrix();
        EXPECT_GT(sum_sq_error(gt, est, r, nudge * r.T_gt_est), best) << axis << " " << step;
        nudge = Pose::Identity();
        nudge.translation() = step * Eigen::Vector3d::Unit(axis);
        EXPECT_GT(sum_sq_error(gt, est, r, nudge * r.T_gt_est), best) << axis << " " << step;
      }
    }
  }
}

// The statistics follow numpy (evaluate_ate.py): rmse, mean, median, population std, min, max.
TEST(Ate, StatisticsMatchTheTumDefinitions) {
  std::vector<StampedPose> gt, est;
  const double offsets[] = {3.0, 1.0, 4.0, 2.0};  // errors 1..4 in scrambled order
  const Eigen::Vector3d dirs[] = {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(),
                                  Eigen::Vector3d::UnitZ(), -Eigen::Vector3d::UnitX()};
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d p(i, 2.0 * i, -i);
    gt.push_back(at(i, p));
    est.push_back(at(i, p + offsets[i] * dirs[i]));
  }
  AteResult r = evaluate_ate(gt, est, {.align = false});
  EXPECT_DOUBLE_EQ(r.rmse_m, std::sqrt(7.5));
  EXPECT_DOUBLE_EQ(r.mean_m, 2.5);
  EXPECT_DOUBLE_EQ(r.median_m, 2.5);
  EXPECT_DOUBLE_EQ(r.std_m, std::sqrt(1.25));
  EXPECT_DOUBLE_EQ(r.min_m, 1.0);
  EXPECT_DOUBLE_EQ(r.max_m, 4.0);
  EXPECT_EQ(r.errors_m, (std::vector<double>{3.0, 1.0, 4.0, 2.0}));  // in match order

  // Odd count: the middle value.
  gt.push_back(at(4, Eigen::Vector3d::Zero()));
  est.push_back(at(4, Eigen::Vector3d(0, 0, 10)));
  r = evaluate_ate(gt, est, {.align = false});
  EXPECT_DOUBLE_EQ(r.median_m, 3.0);
  EXPECT_DOUBLE_EQ(r.max_m, 10.0);
}

// Ground truth at 100 Hz with a 0.2 s hole; estimates at 30 Hz with +-4 ms jitter, every 7th
// missing, and a few after the ground truth ends. Each estimate must get its nearest ground-truth
// pose when that is within max_dt and none otherwise (no two estimates compete for one
// ground-truth pose here: 30 Hz estimates are >= 25 ms apart and the 100 Hz ground truth has a
// pose within 5 ms of each, outside the hole).
TEST(AteAssociation, JitterMissingPosesAndGaps) {
  std::vector<StampedPose> gt, est;
  for (int i = 0; i < 300; ++i) {
    const double t = 1000.0 + 0.01 * i;
    if (t > 1001.0 && t < 1001.2) continue;  // the hole
    gt.push_back(at(t, test::loop_position(0.01 * i)));
  }
  for (int k = 0; k < 95; ++k) {
    if (k % 7 == 3) continue;
    const double t = 1000.0 + k / 30.0 + 0.004 * ((k % 3) - 1);
    est.push_back(at(t, test::loop_position(t - 1000.0)));
  }
  const double max_dt = 0.02;
  const auto matches = associate_by_time(gt, est, max_dt);

  // Reference: brute-force nearest ground-truth pose of each estimate.
  std::size_t expected = 0, rejected_in_hole = 0, rejected_after_end = 0;
  for (std::size_t e = 0; e < est.size(); ++e) {
    double best = std::numeric_limits<double>::infinity();
    std::size_t best_g = 0;
    for (std::size_t g = 0; g < gt.size(); ++g) {
      const double dt = std::abs(gt[g].timestamp_s - est[e].timestamp_s);
      if (dt < best) best = dt, best_g = g;
    }
    const auto it = std::find_if(matches.begin(), matches.end(),
                                 [&](const PoseMatch& m) { return m.est_index == e; });
    if (best < max_dt) {
      ++expected;
      ASSERT_NE(it, matches.end()) << "estimate " << e << " at " << est[e].timestamp_s;
      EXPECT_EQ(it->gt_index, best_g);
      EXPECT_DOUBLE_EQ(it->dt_s, best);
    } else {
      EXPECT_EQ(it, matches.end()) << "estimate " << e << " matched at dt " << it->dt_s;
      (est[e].timestamp_s > 1002.99 ? rejected_after_end : rejected_in_hole)++;
    }
  }
  EXPECT_EQ(matches.size(), expected);
  EXPECT_EQ(expected, 74u);  // 81 estimates less those below
  // k = 91..93 (t >= 1003.03; k = 90 at 1002.996 still matches the last pose, 1002.99).
  EXPECT_EQ(rejected_after_end, 3u);
  // k = 32..35 (t = 1001.07..1001.17); k = 31 is missing, k = 30 and 36 are near the edges.
  EXPECT_EQ(rejected_in_hole, 4u);
  for (const PoseMatch& m : matches) EXPECT_LT(m.dt_s, max_dt);
  for (std::size_t i = 1; i < matches.size(); ++i)
    EXPECT_LT(gt[matches[i - 1].gt_index].timestamp_s, gt[matches[i].gt_index].timestamp_s);

  EXPECT_EQ(evaluate_ate(gt, est).matched, expected);
  // A wider window also matches estimates in the hole and after the end.
  EXPECT_GT(associate_by_time(gt, est, 0.2).size(), expected);
}

// Closest pairs first, one-to-one: two estimates near the same ground-truth pose do not both
// take it.
TEST(AteAssociation, GreedyOneToOneClosestFirst) {
  const std::vector<StampedPose> gt = {at(1.00, {0, 0, 0}), at(1.10, {1, 0, 0})};
  const std::vector<StampedPose> est = {at(1.012, {0, 0, 0}), at(1.005, {0, 0, 0})};
  auto m = associate_by_time(gt, est, 0.02);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].gt_index, 0u);
  EXPECT_EQ(m[0].est_index, 1u);  // 5 ms beats 12 ms
  EXPECT_NEAR(m[0].dt_s, 0.005, 1e-12);

  // With a 0.1 s window the loser falls back to the other ground-truth pose (88 ms away).
  m = associate_by_time(gt, est, 0.1);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_EQ(m[0].gt_index, 0u);
  EXPECT_EQ(m[0].est_index, 1u);
  EXPECT_EQ(m[1].gt_index, 1u);
  EXPECT_EQ(m[1].est_index, 0u);
}

// associate.py keeps a pair only when |dt| < max_difference, strictly.
TEST(AteAssociation, MaxDtIsExclusiveLikeTum) {
  const std::vector<StampedPose> gt = {at(1.0, {0, 0, 0})};
  const std::vector<StampedPose> est = {at(1.5, {0, 0, 0})};  // dt exactly 0.5 in binary
  EXPECT_TRUE(associate_by_time(gt, est, 0.5).empty());
  EXPECT_EQ(associate_by_time(gt, est, 0.5000001).size(), 1u);
  EXPECT_EQ(associate_by_time(est, gt, 0.5000001).size(), 1u);
}

TEST(AteAssociation, InputOrderDoesNotMatter) {
  const auto gt = loop_trajectory(60);
  auto est = perturbed(gt, {0.01, 0, 0}, {0, 0, 0.03}, some_rigid_motion());
  for (auto& p : est) p.timestamp_s += 0.003;
  const AteResult sorted = evaluate_ate(gt, est);

  std::mt19937 rng(7);
  auto gt_shuffled = gt, est_shuffled = est;
  std::shuffle(gt_shuffled.begin(), gt_shuffled.end(), rng);
  std::shuffle(est_shuffled.begin(), est_shuffled.end(), rng);
  const AteResult shuffled = evaluate_ate(gt_shuffled, est_shuffled);
  ASSERT_EQ(shuffled.matched, sorted.matched);
  EXPECT_NEAR(shuffled.rmse_m, sorted.rmse_m, 1e-12);
  for (std::size_t i = 0; i < sorted.matched; ++i) {
    EXPECT_EQ(gt_shuffled[shuffled.matches[i].gt_index].timestamp_s,
              gt[sorted.matches[i].gt_index].timestamp_s);
    EXPECT_EQ(est_shuffled[shuffled.matches[i].est_index].timestamp_s,
              est[sorted.matches[i].est_index].timestamp_s);
    EXPECT_NEAR(shuffled.errors_m[i], sorted.errors_m[i], 1e-12);
  }
}

TEST(AteErrors, FewerThanThreeMatchesSaysHowMany) {
  const auto gt = loop_trajectory(30);
  auto est = gt;
  for (std::size_t i = 2; i < est.size(); ++i) est[i].timestamp_s += 100.0;  // 2 still match
  const Error e = error_of([&] { evaluate_ate(gt, est); });
  EXPECT_EQ(e.code(), ErrorCode::InvalidData);
  EXPECT_TRUE(contains(e.what(), "only 2 of 30")) << e.what();
  EXPECT_TRUE(contains(e.what(), "max_dt 0.02 s")) << e.what();
  EXPECT_TRUE(contains(e.what(), "at least 3")) << e.what();
  est[2].timestamp_s -= 100.0;  // three match: fine
  EXPECT_EQ(evaluate_ate(gt, est).matched, 3u);
}

TEST(AteErrors, EmptyNonFiniteAndBadParams) {
  const auto gt = loop_trajectory(10);
  Error e = error_of([&] { evaluate_ate({}, gt); });
  EXPECT_EQ(e.code(), ErrorCode::InvalidData);
  EXPECT_TRUE(contains(e.what(), "ground-truth")) << e.what();
  e = error_of([&] { evaluate_ate(gt, {}); });
  EXPECT_EQ(e.code(), ErrorCode::InvalidData);
  EXPECT_TRUE(contains(e.what(), "estimated")) << e.what();

  const double nan = std::numeric_limits<double>::quiet_NaN();
  auto bad = gt;
  bad[4].T_wc.translation().y() = nan;
  e = error_of([&] { evaluate_ate(gt, bad); });
  EXPECT_EQ(e.code(), ErrorCode::InvalidData);
  EXPECT_TRUE(contains(e.what(), "estimated pose 4")) << e.what();
  bad = gt;
  bad[6].T_wc.linear()(1, 2) = std::numeric_limits<double>::infinity();
  e = error_of([&] { evaluate_ate(bad, gt); });
  EXPECT_TRUE(contains(e.what(), "ground-truth pose 6")) << e.what();
  bad = gt;
  bad[1].timestamp_s = nan;
  e = error_of([&] { evaluate_ate(gt, bad); });
  EXPECT_EQ(e.code(), ErrorCode::InvalidData);
  EXPECT_TRUE(contains(e.what(), "timestamp")) << e.what();

  for (const double dt : {0.0, -0.02, nan, std::numeric_limits<double>::infinity()}) {
    e = error_of([&] { evaluate_ate(gt, gt, {.max_dt_s = dt}); });
    EXPECT_EQ(e.code(), ErrorCode::InvalidArgument) << dt;
    EXPECT_TRUE(contains(e.what(), "max_dt_s")) << e.what();
    e = error_of([&] { associate_by_time(gt, gt, dt); });
    EXPECT_EQ(e.code(), ErrorCode::InvalidArgument) << dt;
  }
}

}  // namespace
}  // namespace hivox

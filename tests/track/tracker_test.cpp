// Frame-to-model ICP on the synthetic desk, whose poses and depth are known exactly: small
// known motions are recovered, a whole noisy trajectory stays within 1 cm ATE, and a frame of
// garbage depth is flagged lost and left out of the map.

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "hivox/core/error.h"
#include "hivox/eval/trajectory_eval.h"
#include "hivox/pipeline/reconstruction.h"
#include "hivox/synth/render.h"
#include "hivox/synth/synthetic_dataset.h"
#include "hivox/track/tracker.h"

namespace hivox {
namespace {

double angle_deg(const Pose& a, const Pose& b) {
  return rotation_angle_rad(a.inverse() * b) * 180.0 / std::numbers::pi;
}
double distance_m(const Pose& a, const Pose& b) {
  return (a.translation() - b.translation()).norm();
}

Pose motion(const Eigen::Vector3d& t_m, const Eigen::Vector3d& axis, double deg) {
  Pose T = Pose::Identity();
  T.linear() =
      Eigen::AngleAxisd(deg * std::numbers::pi / 180.0, axis.normalized()).toRotationMatrix();
  T.translation() = t_m;
  return T;
}

TEST(Tracker, RecoversSmallKnownMotionsOnCleanDepth) {
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=120&noise=none"));
  ReconstructionParams params;
  params.raycast_every_frame = false;
  Reconstruction recon(params, data.info().rig);
  for (std::size_t i = 0; i < 3; ++i) {
    const RgbdFrame frame = data.read(i);
    recon.integrate(frame, *frame.T_wc_gt);
  }
  const PinholeCamera cam = data.camera();
  const Pose T0 = *data.read(0).T_wc_gt;
  const RaycastResult model = recon.render(cam, T0);  // a copy: render reuses its buffers

  const Pose motions[] = {
      motion({0.01, 0.0, 0.0}, {0, 1, 0}, 0.0),       motion({0.0, -0.008, 0.012}, {0, 1, 0}, 0.0),
      motion({0.0, 0.0, 0.0}, {0, 1, 0}, 1.5),        motion({0.0, 0.0, 0.0}, {1, 0, 0.3}, -1.0),
      motion({0.0, 0.0, 0.0}, {0, 0, 1}, 2.0),        motion({0.006, 0.005, -0.01}, {1, 2, 3}, 1.2),
      motion({-0.015, 0.01, 0.0}, {-2, 1, 0.5}, 2.5),
  };
  Tracker tracker(TrackParams{}, params.fusion.depth_range);
  for (const Pose& delta : motions) {
    const Pose T_true = T0 * delta;
    const RenderedFrame frame = render(data.scene(), cam, T_true);
    const TrackResult r = tracker.track(frame.depth_m, cam, model, T0);
    SCOPED_TRACE("motion " + std::to_string(delta.translation().norm() * 1e3) + " mm, " +
                 std::to_string(angle_deg(delta, Pose::Identity())) + " deg");
    EXPECT_EQ(r.quality, TrackingQuality::Good);
    EXPECT_LE(distance_m(r.T_wc, T_true), 0.001);
    EXPECT_LE(angle_deg(r.T_wc, T_true), 0.1);
    EXPECT_GT(r.inlier_ratio, 0.8);
    EXPECT_LT(r.rms_m, 0.002);
    EXPECT_GT(r.condition, 1e-3);
  }
}

// The tracking benchmark's fixed setting: a 5 mm grid, truncation 20 mm.
ReconstructionParams fixed_5mm() {
  ReconstructionParams params;
  params.map.levels = 1;
  params.map.voxel_size_m = 0.005f;
  params.map.truncation_m = 0.02f;
  return params;
}

// The whole online loop on the noisy synthetic desk: the only pose given is the first.
TEST(Tracker, NoisyTrajectoryStaysWithinOneCentimetre) {
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=120&noise=kinect"));
  Reconstruction recon(fixed_5mm(), data.info().rig);
  std::vector<StampedPose> gt;
  for (std::size_t i = 0; i < data.size(); ++i) {
    const RgbdFrame frame = data.read(i);
    const FrameStats& s = recon.track_and_integrate(frame, 0.0, data.trajectory().front().T_wc);
    EXPECT_NE(s.tracking, TrackingQuality::Lost) << "frame " << i;
    gt.push_back({frame.timestamp_s, *frame.T_wc_gt});
  }
  const AteResult ate = evaluate_ate(gt, recon.trajectory());
  EXPECT_EQ(ate.matched, static_cast<int64_t>(data.size()));
  EXPECT_LE(ate.rmse_m, 0.01);
  EXPECT_LE(ate.max_m, 0.025);
  std::printf("synthetic desk, Kinect noise, %zu frames: ATE RMSE %.2f mm, max %.2f mm\n",
              data.size(), ate.rmse_m * 1e3, ate.max_m * 1e3);
}

TEST(Tracker, GarbageDepthIsLostAndNotFused) {
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=120&noise=kinect"));
  Reconstruction recon(fixed_5mm(), data.info().rig);
  for (std::size_t i = 0; i < 6; ++i)
    ASSERT_NE(recon.track_and_integrate(data.read(i), 0.0, data.trajectory().front().T_wc).tracking,
              TrackingQuality::Lost);
  const int64_t blocks = recon.map().blocks_in_use();
  const Pose before = recon.trajectory().back().T_wc;

  RgbdFrame garbage = data.read(6);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> depth(0.4f, 3.0f);
  for (int y = 0; y < garbage.depth_m.height(); ++y)
    for (int x = 0; x < garbage.depth_m.width(); ++x) garbage.depth_m(x, y) = depth(rng);
  const FrameStats& s = recon.track_and_integrate(garbage);
  EXPECT_EQ(s.tracking, TrackingQuality::Lost);
  EXPECT_FALSE(s.fused);
  EXPECT_EQ(recon.map().blocks_in_use(), blocks) << "nothing of the garbage frame was fused";
  EXPECT_TRUE(recon.trajectory().back().T_wc.isApprox(before)) << "the previous pose is kept";

  RgbdFrame empty = data.read(7);
  empty.depth_m.fill(0.0f);
  EXPECT_EQ(recon.track_and_integrate(empty).tracking, TrackingQuality::Lost);
  EXPECT_EQ(recon.map().blocks_in_use(), blocks);

  // Real depth again: tracking resumes from the kept pose.
  const RgbdFrame next = data.read(8);
  const FrameStats& resumed = recon.track_and_integrate(next);
  EXPECT_EQ(resumed.tracking, TrackingQuality::Good);
  EXPECT_TRUE(resumed.fused);
  EXPECT_LE(distance_m(recon.trajectory().back().T_wc, *next.T_wc_gt), 0.01);
}

TEST(MotionPrior, StartsFromTheLastMotionAndForgetsItWhenLost) {
  const Pose a(Eigen::Translation3d(1, 0, 0) * Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitZ()));
  const Pose b(Eigen::Translation3d(1.02, 0.01, 0) *
               Eigen::AngleAxisd(0.13, Eigen::Vector3d::UnitZ()));
  MotionPrior prior(true);
  EXPECT_TRUE(prior.start(a).isApprox(a)) << "no motion known yet";
  TrackResult tracked;
  tracked.quality = TrackingQuality::Good;
  tracked.T_wc = b;
  EXPECT_TRUE(prior.keep(a, tracked).isApprox(b));
  // The next frame starts from b moved by the motion a -> b.
  const Pose expected = b * (a.inverse() * b);
  EXPECT_TRUE(prior.start(b).isApprox(expected));
  // A lost frame keeps the previous pose and forgets the motion.
  TrackResult lost;
  lost.quality = TrackingQuality::Lost;
  lost.T_wc = expected;
  EXPECT_TRUE(prior.keep(b, lost).isApprox(b));
  EXPECT_TRUE(prior.start(b).isApprox(b));
  // Poor frames are kept.
  tracked.quality = TrackingQuality::Poor;
  EXPECT_TRUE(prior.keep(a, tracked).isApprox(b));
  prior.restart();
  EXPECT_TRUE(prior.start(b).isApprox(b));
  // Without the constant-velocity model, tracking starts from the previous pose.
  MotionPrior still(false);
  tracked.quality = TrackingQuality::Good;
  still.keep(a, tracked);
  EXPECT_TRUE(still.start(b).isApprox(b));
}

TEST(TrackParams, RejectsNonsense) {
  TrackParams p;
  EXPECT_NO_THROW(p.validate());
  p.iterations = {};
  EXPECT_THROW(p.validate(), Error);
  p = {};
  p.max_distance_m = -1.0f;
  EXPECT_THROW(p.validate(), Error);
  EXPECT_THROW(Tracker(TrackParams{}, DepthRange{2.0f, 1.0f}), Error);
  EXPECT_EQ(parse_robust_loss("tukey"), RobustLoss::Tukey);
  EXPECT_THROW(parse_robust_loss("cauchy"), Error);
}

}  // namespace
}  // namespace hivox

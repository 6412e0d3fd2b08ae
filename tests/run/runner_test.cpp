// The library-level run: the frame rules (first frame, lost frames, frames without a pose), the
// files it writes, stopping early, and its errors. The reference is the same frames driven
// through Reconstruction by hand.

#include "hivox/run/runner.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <set>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "hivox/core/error.h"
#include "hivox/io/trajectory_io.h"
#include "hivox/mesh/extract_mesh.h"
#include "hivox/synth/synthetic_dataset.h"
#include "run/small_run.h"
#include "test_util.h"

namespace hivox {
namespace {

using test::small_run;

SyntheticDataset desk(int frames) {
  return test::small_desk(frames);
}

/// What a run is compared by: the trajectory and the map's blocks per level.
void expect_same_reconstruction(const Reconstruction& a, const Reconstruction& b) {
  ASSERT_EQ(a.trajectory().size(), b.trajectory().size());
  for (std::size_t i = 0; i < a.trajectory().size(); ++i) {
    EXPECT_EQ(a.trajectory()[i].timestamp_s, b.trajectory()[i].timestamp_s);
    EXPECT_TRUE(a.trajectory()[i].T_wc.isApprox(b.trajectory()[i].T_wc, 0.0)) << "pose " << i;
  }
  EXPECT_EQ(a.map().blocks_per_level(), b.map().blocks_per_level());
  EXPECT_EQ(extract_mesh(a.map()).triangle_count(), extract_mesh(b.map()).triangle_count());
}

TEST(Runner, TrackedRunIsTheOnlineLoopFromTheFirstTruePose) {
  SyntheticDataset data = desk(300);  // small steps along the path: ICP keeps up
  RunParams p = small_run();
  p.max_frames = 12;
  const RunResult run = run_reconstruction(data, p);
  // By hand: the first frame at its true pose, then tracking.
  Reconstruction by_hand(p.reconstruction, data.info().rig);
  for (std::size_t i = 0; i < p.max_frames; ++i) {
    const RgbdFrame frame = data.read(i);
    by_hand.track_and_integrate(frame, 0.0, *frame.T_wc_gt);
  }
  expect_same_reconstruction(*run.reconstruction, by_hand);
  EXPECT_TRUE(run.reconstruction->trajectory()[0].T_wc.isApprox(*data.read(0).T_wc_gt));
  const RunSummary& s = run.summary;
  EXPECT_EQ(s.frames_total, 12u);
  EXPECT_EQ(s.frames_fused + s.frames_lost, 12u);
  EXPECT_EQ(s.frames_lost, static_cast<std::size_t>(by_hand.tracking_counts().lost));
  EXPECT_EQ(s.frames_skipped, 0u);
  ASSERT_TRUE(s.ate.has_value()) << "estimated poses against the ground truth";
  EXPECT_LT(s.ate->rmse_m, 0.01);
  EXPECT_GT(s.mesh_triangles, 1000);
  EXPECT_TRUE(s.files.empty()) << "no output folder, no files";
}

TEST(Runner, WritesItsFilesAndStatsCountTheFrames) {
  SyntheticDataset data = desk(6);
  const test::TempDir dir;
  RunParams p = small_run();
  p.poses = PoseSpec::parse("gt");
  p.max_frames = 5;
  p.render_every = 2;
  p.out_dir = dir / "out";
  const RunResult run = run_reconstruction(data, p);
  EXPECT_EQ(run.summary.frames_fused, 5u);
  EXPECT_FALSE(run.summary.ate.has_value()) << "ground-truth poses have no error to report";
  std::set<std::string> names;
  for (const auto& f : run.summary.files) {
    EXPECT_TRUE(std::filesystem::is_regular_file(f)) << f;
    EXPECT_GT(std::filesystem::file_size(f), 0u) << f;
    names.insert(f.filename().string());
  }
  for (const char* name :
       {"trajectory.txt", "mesh.ply", "stats.json", "depth.png", "levels.png",
        "overview_shaded.png", "frame000001_color.png", "frame000003_normals.png"})
    EXPECT_TRUE(names.count(name)) << name;
  EXPECT_EQ(names.size(), 3u + 5u * 4u) << "3 files, renders at the end, from above, frames 1, 3";
  EXPECT_EQ(read_tum_trajectory(p.out_dir / "trajectory.txt").size(), 5u);
  std::ifstream in(p.out_dir / "stats.json");
  const nlohmann::json stats = nlohmann::json::parse(in);
  EXPECT_EQ(stats["frames"], 5);
  EXPECT_EQ(stats["poses"], "gt");
}

TEST(Runner, FramesWithoutAPoseInTheFileAreSkippedAndCounted) {
  SyntheticDataset data = desk(6);
  const test::TempDir dir;
  // A trajectory with the true poses of frames 0, 1, 3 and 4 only.
  std::vector<StampedPose> poses;
  for (std::size_t i : {0, 1, 3, 4}) {
    const RgbdFrame f = data.read(i);
    poses.push_back({f.timestamp_s, *f.T_wc_gt});
  }
  write_tum_trajectory(dir / "poses.txt", poses);
  RunParams p = small_run();
  p.poses = PoseSpec::parse((dir / "poses.txt").string());
  EXPECT_EQ(p.poses.source, PoseSource::File);
  const RunResult run = run_reconstruction(data, p);
  EXPECT_EQ(run.summary.frames_fused, 4u);
  EXPECT_EQ(run.summary.frames_skipped, 2u);
  ASSERT_EQ(run.reconstruction->trajectory().size(), 4u);
  EXPECT_EQ(run.reconstruction->trajectory()[2].timestamp_s, poses[2].timestamp_s);
}

TEST(Runner, StopRequestEndsTheRunWithTheFramesSoFar) {
  SyntheticDataset data = desk(8);
  const test::TempDir dir;
  RunParams p = small_run();
  p.poses = PoseSpec::parse("gt");
  p.out_dir = dir.path();
  std::size_t seen = 0;
  RunCallbacks callbacks;
  callbacks.on_frame = [&](std::size_t i, const FrameStats& s, const Reconstruction& rec,
                           const RgbdFrame&) {
    EXPECT_EQ(i, seen);
    EXPECT_EQ(s.index, i);
    EXPECT_EQ(rec.frame_stats().size(), i + 1);
    ++seen;
  };
  callbacks.stop_requested = [&] { return seen == 3; };
  const RunResult run = run_reconstruction(data, p, callbacks);
  EXPECT_EQ(run.summary.end, RunEnd::StopRequested);
  EXPECT_EQ(run.summary.frames_fused, 3u);
  EXPECT_EQ(read_tum_trajectory(dir / "trajectory.txt").size(), 3u) << "results of those frames";
}

// Stretches of poor tracking in a list of frame verdicts: a stretch runs from one good frame to
// the next, lost frames inside it extend it but are not poor, and each poor frame has one cause.
TEST(Runner, StretchesOfPoorTrackingAreFoundWithTheirCause) {
  const TrackParams track;  // poor below 40 % inliers or a condition of 1e-3
  std::vector<FrameStats> frames;
  auto add = [&](TrackingQuality q, double inliers, double condition) {
    FrameStats f;
    f.index = 10 + frames.size();  // indices of the dataset, not of the list
    f.tracking = q;
    f.track_inlier_ratio = inliers;
    f.track_condition = condition;
    frames.push_back(f);
  };
  const auto G = TrackingQuality::Good, P = TrackingQuality::Poor, L = TrackingQuality::Lost;
  add(G, 0.9, 0.1);
  for (int i = 0; i < 4; ++i) add(P, 0.3, 0.1);  // 11-14: four poor, too short
  add(G, 0.9, 0.1);
  add(P, 0.35, 0.1);  // 16: few inliers
  add(P, 0.2, 0.1);   // 17: few inliers
  add(L, 0.1, 0.0);   // 18: lost, not poor
  add(P, 0.8, 1e-4);  // 19: unconstrained
  add(P, 0.3, 1e-4);  // 20: few inliers (that cause first)
  add(P, 0.7, 5e-4);  // 21: unconstrained
  add(G, 0.9, 0.1);   // 22
  add(P, 0.39, 0.1);  // 23-27: five poor to the end of the list
  for (int i = 0; i < 4; ++i) add(P, 0.25, 0.1);

  const auto expect_stretch = [](const PoorTrackingStretch& got, const PoorTrackingStretch& want) {
    EXPECT_EQ(got.first_index, want.first_index);
    EXPECT_EQ(got.last_index, want.last_index);
    EXPECT_EQ(got.poor, want.poor);
    EXPECT_EQ(got.lost, want.lost);
    EXPECT_EQ(got.few_inliers, want.few_inliers);
    EXPECT_EQ(got.unconstrained, want.unconstrained);
    EXPECT_DOUBLE_EQ(got.min_inlier_ratio, want.min_inlier_ratio);
    EXPECT_DOUBLE_EQ(got.max_inlier_ratio, want.max_inlier_ratio);
  };
  const std::vector<PoorTrackingStretch> s = poor_tracking_stretches(frames, track, 5);
  ASSERT_EQ(s.size(), 2u);
  // The inlier range is that of the frames with too few inliers.
  expect_stretch(s[0], {.first_index = 16,
                        .last_index = 21,
                        .poor = 5,
                        .lost = 1,
                        .few_inliers = 3,
                        .unconstrained = 2,
                        .min_inlier_ratio = 0.2,
                        .max_inlier_ratio = 0.35});
  expect_stretch(s[1], {.first_index = 23,
                        .last_index = 27,
                        .poor = 5,
                        .lost = 0,
                        .few_inliers = 5,
                        .unconstrained = 0,
                        .min_inlier_ratio = 0.25,
                        .max_inlier_ratio = 0.39});
  EXPECT_EQ(poor_tracking_stretches(frames, track, 4).size(), 3u) << "11-14 counts from 4";
  EXPECT_EQ(poor_tracking_stretches(frames, track, 6).size(), 0u);
  EXPECT_TRUE(poor_tracking_stretches({}, track, 1).empty());
}

// A smooth blob leaves ICP a direction it cannot pin down: every frame is poor, none lost, and
// the run says so once, with the cause. The desk, which constrains every direction, does not.
TEST(Runner, AStretchOfPoorTrackingIsAWarning) {
  SyntheticDataset blob(
      parse_synthetic_spec("synthetic:blob?frames=20&noise=none&width=160&height=120"));
  const RunResult run = run_reconstruction(blob, small_run());
  const TrackingCounts& counts = run.reconstruction->tracking_counts();
  EXPECT_EQ(counts.lost, 0);
  ASSERT_GE(counts.poor, 5);
  std::vector<std::string> warned;
  for (const std::string& w : run.summary.warnings)
    if (test::contains(w, "tracking was poor")) warned.push_back(w);
  ASSERT_EQ(warned.size(), 1u) << ::testing::PrintToString(run.summary.warnings);
  EXPECT_TRUE(test::contains(warned[0], fmt::format("poor on {} frames in a row", counts.poor)))
      << warned[0];
  EXPECT_TRUE(test::contains(warned[0], "a direction of motion unconstrained")) << warned[0];
  EXPECT_FALSE(test::contains(warned[0], "inliers")) << warned[0];

  SyntheticDataset data = desk(300);
  RunParams p = small_run();
  p.max_frames = 20;
  const RunResult good = run_reconstruction(data, p);
  EXPECT_EQ(good.reconstruction->tracking_counts().poor, 0);
  EXPECT_TRUE(good.summary.warnings.empty()) << ::testing::PrintToString(good.summary.warnings);
}

TEST(Runner, BadSettingsAreNamed) {
  SyntheticDataset data = desk(2);
  auto error_of = [&](const RunParams& p) {
    try {
      run_reconstruction(data, p);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  RunParams p = small_run();
  p.render_every = -1;
  EXPECT_TRUE(test::contains(error_of(p), "render_every")) << error_of(p);
  p = small_run();
  p.reconstruction.raycast_every_frame = false;
  EXPECT_TRUE(test::contains(error_of(p), "raycast")) << error_of(p);
  p = small_run();
  p.poses = PoseSpec::parse("/no/such/trajectory.txt");
  EXPECT_TRUE(test::contains(error_of(p), "/no/such/trajectory.txt")) << error_of(p);
  p = small_run();
  p.reconstruction.map.truncation_m = -1.0f;
  EXPECT_TRUE(test::contains(error_of(p), "truncation_m")) << error_of(p);
  EXPECT_THROW(PoseSpec::parse(""), Error);
}

}  // namespace
}  // namespace hivox

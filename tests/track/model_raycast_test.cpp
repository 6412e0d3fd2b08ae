// The pipeline's per-frame raycast of the model (the tracking input): its rays start at the depth
// just fused and, where the frame has none, at the previous raycast's depth warped into the new
// view. The starts are a search order, not a method: the model seen is the same as when every
// ray without a measured depth searches its whole range.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "hivox/core/error.h"
#include "hivox/io/map_file.h"
#include "hivox/pipeline/reconstruction.h"
#include "hivox/raycast/hints.h"
#include "hivox/synth/synthetic_dataset.h"
#include "test_util.h"

namespace hivox {
namespace {

TEST(ModelRaycast, PreviousRaycastHintsFindTheSameSurfaces) {
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=120&noise=none"));
  ReconstructionParams params;
  params.map.levels = 1;
  params.map.voxel_size_m = 0.005f;
  params.map.truncation_m = 0.02f;
  params.previous_raycast_hints = true;
  Reconstruction with(params, data.info().rig);
  params.previous_raycast_hints = false;
  Reconstruction without(params, data.info().rig);
  // From frame 4 on, a band of the depth image is missing (as where a sensor sees nothing): the
  // model still holds the surface there from the first frames.
  const int hole_x0 = 200, hole_x1 = 360;
  int64_t compared = 0, differ = 0, far = 0, hole_hits = 0, gained = 0;
  for (std::size_t i = 0; i < 24; ++i) {
    RgbdFrame frame = data.read(i);
    if (i >= 4)
      for (int y = 0; y < frame.depth_m.height(); ++y)
        for (int x = hole_x0; x < hole_x1; ++x) frame.depth_m(x, y) = 0.0f;
    const FrameStats& sw = with.integrate(frame, *frame.T_wc_gt);
    const FrameStats& so = without.integrate(frame, *frame.T_wc_gt);
    if (i < 5) continue;  // the first frame with a hole has no hinted raycast before it
    const RaycastResult& a = with.last_raycast();
    const RaycastResult& b = without.last_raycast();
    const int n = params.track.model_subsample;
    for (int y = 0; y < a.depth_m.height(); ++y)
      for (int x = 0; x < a.depth_m.width(); ++x) {
        ++compared;
        if (a.hit(x, y) != b.hit(x, y)) {
          ++differ;
          continue;
        }
        if (!a.hit(x, y)) continue;
        far += std::abs(a.depth_m(x, y) - b.depth_m(x, y)) > 2 * params.map.voxel_size_m;
        const int fx = n * x + n / 2;
        hole_hits += fx >= hole_x0 && fx < hole_x1;
      }
    gained += sw.raycast_hits_at_hint - so.raycast_hits_at_hint;
  }
  EXPECT_GT(hole_hits, 10000);
  // Most hits in the hole are found at the warped hint instead of by a march.
  EXPECT_GT(gained, 0.8 * hole_hits);
  EXPECT_LT(differ, compared / 1000);
  EXPECT_LT(far, compared / 1000);
  std::printf(
      "%lld pixels compared, %lld hit by one only, %lld on different surfaces; %lld hole "
      "hits, %lld more found at a hint\n",
      static_cast<long long>(compared), static_cast<long long>(differ), static_cast<long long>(far),
      static_cast<long long>(hole_hits), static_cast<long long>(gained));
}

/// Every pixel of two raycasts the same, bit for bit.
int64_t differing_pixels(const RaycastResult& a, const RaycastResult& b) {
  int64_t differ = 0;
  for (int y = 0; y < a.depth_m.height(); ++y)
    for (int x = 0; x < a.depth_m.width(); ++x)
      differ += !(a.depth_m(x, y) == b.depth_m(x, y) && a.levels(x, y) == b.levels(x, y) &&
                  a.points_w(x, y) == b.points_w(x, y) && a.normals_w(x, y) == b.normals_w(x, y));
  return differ;
}

// The per-frame raycast's hints come from one helper (FrameHints), which the pipeline, the
// benchmarks and the bindings call. Its hints are the frame's depth at the raycast's pixel
// centres and the previous raycast warped with a gap of one truncation band: a raycast given
// hints built so by hand gives the pipeline's pixels, bit for bit.
TEST(ModelRaycast, FrameHintsAreTheDepthJustFusedAndThePreviousRaycastWarped) {
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=120&noise=kinect"));
  ReconstructionParams params;
  params.map.levels = 2;
  params.map.voxel_size_m = 0.005f;
  params.map.truncation_m = 0.02f;
  Reconstruction rec(params, data.info().rig);
  const PinholeCamera& depth_camera = data.info().rig.depth_camera;
  const int n = params.track.model_subsample;
  const PinholeCamera camera = depth_camera.subsampled(n);
  RaycastResult previous;
  int64_t compared = 0, with_fallback = 0;
  for (std::size_t i = 0; i < 8; ++i) {
    const RgbdFrame frame = data.read(i);
    const FrameStats& s = rec.integrate(frame, *frame.T_wc_gt);
    if (i > 0) {
      // By hand: the frame's depth at the centres of n x n pixel blocks, the previous raycast
      // warped into this view.
      DepthImage start(camera.width, camera.height);
      for (int y = 0; y < camera.height; ++y)
        for (int x = 0; x < camera.width; ++x)
          start(x, y) = frame.depth_m(n * x + n / 2, n * y + n / 2);
      DepthImage warped;
      warp_raycast_depth(previous, camera, *frame.T_wc_gt, params.map.truncation_m, &warped);
      Raycaster by_hand(params.raycast);
      RaycastStats hand_stats;
      const RaycastResult& a =
          by_hand.raycast(rec.map(), camera, *frame.T_wc_gt, params.fusion.depth_range,
                          {&start, &warped}, &hand_stats);
      EXPECT_EQ(differing_pixels(a, rec.last_raycast()), 0) << "frame " << i;
      EXPECT_EQ(hand_stats.found_at_hint, s.raycast_hits_at_hint) << "frame " << i;
      // The helper on its own gives the same hints.
      FrameHints helper;
      const RaycastHints hints = helper.build(frame.depth_m, depth_camera, n, *frame.T_wc_gt,
                                              &previous, params.map.truncation_m);
      ASSERT_NE(hints.start_m, nullptr);
      ASSERT_NE(hints.fallback_m, nullptr);
      EXPECT_EQ(hints.start_m->width(), camera.width);
      for (std::size_t k = 0; k < start.size(); ++k) {
        ASSERT_EQ(hints.start_m->data()[k], start.data()[k]) << k;
        ASSERT_EQ(hints.fallback_m->data()[k], warped.data()[k]) << k;
        with_fallback += warped.data()[k] > 0.0f;
      }
      compared += static_cast<int64_t>(start.size());
    }
    previous = rec.last_raycast();
  }
  EXPECT_GT(with_fallback, compared / 2) << "the warped raycast covers most pixels";
  // Without a previous raycast of the raycast's size there is no fallback.
  FrameHints helper;
  const RgbdFrame frame = data.read(0);
  EXPECT_EQ(helper.build(frame.depth_m, depth_camera, n, *frame.T_wc_gt, nullptr, 0.02f).fallback_m,
            nullptr);
  EXPECT_EQ(helper.build(frame.depth_m, depth_camera, 1, *frame.T_wc_gt, &previous, 0.02f).start_m,
            &frame.depth_m)
      << "at full resolution the frame's own depth is the start hint";
  EXPECT_THROW(helper.build(frame.depth_m, camera, n, *frame.T_wc_gt, nullptr, 0.02f), Error);
}

/// ReconstructionParams::refine_after_raycast: a frame's model (what the next frame tracks
/// against) is raycast from the map before that frame's splits and merges, which show from the
/// next raycast on; the map itself is the same as when refining first. The map before the
/// refinement is rebuilt from a saved copy of the map a frame earlier, the frame fused into it
/// without refining.
TEST(ModelRaycast, RefiningAfterTheRaycastLeavesTheModelBeforeTheEdits) {
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=30&noise=kinect"));
  const CameraRig& rig = data.info().rig;
  ReconstructionParams params;            // 3 levels from 2 mm
  params.previous_raycast_hints = false;  // every raycast's hints from its frame alone
  Reconstruction first(params, rig);
  params.refine_after_raycast = true;
  Reconstruction after(params, rig);
  test::TempDir dir;
  constexpr std::size_t kFrame = 12;  // refined (every 2nd frame from the first)
  for (std::size_t i = 0; i <= kFrame; ++i) {
    const RgbdFrame f = data.read(i);
    if (i == kFrame)
      write_map_file(dir.path() / "before.hvx", after.map(), params.fusion, after.session());
    const FrameStats& a = first.integrate(f, *f.T_wc_gt);
    const FrameStats& b = after.integrate(f, *f.T_wc_gt);
    EXPECT_EQ(a.splits, b.splits) << "frame " << i;
    EXPECT_EQ(a.merges, b.merges) << "frame " << i;
  }
  const FrameStats& last = after.frame_stats().back();
  ASSERT_GT(last.splits + last.merges, 0) << "frame " << kFrame << " refines";
  // The same map (the files hold the blocks in a canonical order).
  write_map_file(dir.path() / "first.hvx", first.map(), params.fusion, first.session());
  write_map_file(dir.path() / "after.hvx", after.map(), params.fusion, after.session());
  EXPECT_EQ(test::file_bytes(dir.path() / "first.hvx"), test::file_bytes(dir.path() / "after.hvx"));

  // The frame fused into the map before it, not refined (the next refinement a call away).
  LoadedMap before = read_map_file(dir.path() / "before.hvx", params.map);
  ReconstructionParams no_refine = params;
  no_refine.refine.every_n_frames = 1000;
  Reconstruction fused(no_refine, rig, std::move(before.map), after.session());
  const RgbdFrame f = data.read(kFrame);
  fused.integrate(f, *f.T_wc_gt);
  ASSERT_EQ(fused.frame_stats().back().splits + fused.frame_stats().back().merges, 0);
  const RaycastResult& model = after.last_raycast();
  const RaycastResult& expected = fused.last_raycast();
  const RaycastResult& refined = first.last_raycast();
  ASSERT_EQ(model.depth_m.size(), expected.depth_m.size());
  int64_t differ = 0, differ_refined = 0, hits = 0;
  for (std::size_t k = 0; k < model.depth_m.size(); ++k) {
    hits += model.depth_m.data()[k] > 0.0f;
    differ += model.depth_m.data()[k] != expected.depth_m.data()[k];
    differ_refined += model.depth_m.data()[k] != refined.depth_m.data()[k];
  }
  std::printf(
      "[ model    ] frame %zu: %lld splits, %lld merges; %lld hits, %lld pixels apart "
      "from the raycast of the map before them, %lld from the one after\n",
      kFrame, static_cast<long long>(last.splits), static_cast<long long>(last.merges),
      static_cast<long long>(hits), static_cast<long long>(differ),
      static_cast<long long>(differ_refined));
  EXPECT_GT(hits, static_cast<int64_t>(model.depth_m.size() / 2));
  EXPECT_EQ(differ, 0);
  EXPECT_GT(differ_refined, 0) << "the edits change the model a little";
}

}  // namespace
}  // namespace hivox

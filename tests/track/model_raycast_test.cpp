// The pipeline's per-frame raycast of the model (the tracking input): its rays start at the depth
// just fused and, where the frame has none, at the previous raycast's depth warped into the new
// view. The starts are a search order, not a method: the model seen is the same as when every
// ray without a measured depth searches its whole range.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "hivox/pipeline/reconstruction.h"
#include "hivox/synth/synthetic_dataset.h"

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

}  // namespace
}  // namespace hivox

#include "hivox/raycast/hints.h"

#include "hivox/core/error.h"
#include "hivox/raycast/raycaster.h"

namespace hivox {

RaycastHints FrameHints::build(const DepthImage& depth_m, const PinholeCamera& depth_camera,
                               int subsample, const Pose& T_wc, const RaycastResult* previous,
                               float truncation_m) {
  if (subsample < 1)
    fail(ErrorCode::InvalidArgument, "raycast hints: subsample must be >= 1, got {}", subsample);
  if (depth_m.width() != depth_camera.width || depth_m.height() != depth_camera.height)
    fail(ErrorCode::InvalidArgument, "raycast hints: depth image is {}x{} but the camera is {}x{}",
         depth_m.width(), depth_m.height(), depth_camera.width, depth_camera.height);
  const PinholeCamera camera = depth_camera.subsampled(subsample);
  RaycastHints hints;
  // The frame was just fused from this pose: its depth tells each ray where to start.
  hints.start_m = &depth_m;
  if (subsample > 1) {
    const int n = subsample;
    start_.resize(camera.width, camera.height);
    for (int y = 0; y < camera.height; ++y)
      for (int x = 0; x < camera.width; ++x) start_(x, y) = depth_m(n * x + n / 2, n * y + n / 2);
    hints.start_m = &start_;
  }
  // Where the frame has no depth, or the search at its depth fails (a depth in front of the
  // model's surface, or on voxels not observed yet), the surface the previous raycast saw, seen
  // from here.
  if (previous != nullptr && previous->camera.width == camera.width &&
      previous->camera.height == camera.height && !previous->depth_m.empty()) {
    warp_raycast_depth(*previous, camera, T_wc, truncation_m, &warped_, &scratch_);
    hints.fallback_m = &warped_;
  }
  return hints;
}

}  // namespace hivox

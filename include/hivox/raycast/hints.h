#pragma once
/// @file
/// Where a raycast's rays look for the surface first: per-pixel depth hints, and the one helper
/// that builds the per-frame model raycast's hints for the pipeline, the benchmarks and the
/// bindings alike.

#include "hivox/core/camera.h"
#include "hivox/core/image.h"
#include "hivox/core/pose.h"
#include "hivox/raycast/warp.h"

namespace hivox {

struct RaycastResult;

/// Per-pixel depths (metres, 0 = none) near which rays search for the surface before they march,
/// each the size of the raycast's camera; either may be null (see Raycaster::raycast).
struct RaycastHints {
  const DepthImage* start_m = nullptr;     ///< e.g. the depth just fused from this pose
  const DepthImage* fallback_m = nullptr;  ///< e.g. the previous raycast warped into this view
  bool empty() const { return start_m == nullptr && fallback_m == nullptr; }
};

/// Builds the hints of the raycast that follows fusing a frame: the frame's depth as the start
/// hint (sampled at the raycast's pixel centres when it runs at a lower resolution), and where
/// there is a previous raycast of the same size, its depth warped into the new view as the
/// fallback (warp_raycast_depth with a gap of one truncation band). Keeps its images between
/// calls; the hints it returns point into them until the next call.
class FrameHints {
 public:
  /// Hints for raycasting `depth_camera.subsampled(subsample)` from `T_wc` after fusing
  /// `depth_m` (the frame, seen by `depth_camera`). `previous` (optional): the last raycast.
  RaycastHints build(const DepthImage& depth_m, const PinholeCamera& depth_camera, int subsample,
                     const Pose& T_wc, const RaycastResult* previous, float truncation_m);

 private:
  DepthImage start_;   ///< the frame's depth at the raycast's resolution, when it differs
  DepthImage warped_;  ///< the previous raycast's depth seen from the new pose
  WarpScratch scratch_;
};

}  // namespace hivox

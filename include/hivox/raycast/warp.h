#pragma once
/// @file
/// A raycast's surface seen from another pose: the forward warp that gives the per-frame raycast
/// its fallback hints (hivox/raycast/hints.h).

#include <vector>

#include "hivox/core/camera.h"
#include "hivox/core/image.h"
#include "hivox/core/pose.h"

namespace hivox {

struct RaycastResult;

/// Images warp_raycast_depth keeps between calls (allocating and first touching them anew costs
/// about as much as the warp itself).
struct WarpScratch {
  DepthImage nearest, row_min;
  std::vector<DepthImage> partial;  ///< the landings of threads other than the first
};

/// The depth at which the surface points of raycast `from` are seen by `camera` from pose
/// `T_wc` (a forward warp): each hit lands on its nearest pixel, with the depth at which its
/// tangent plane (the hit's normal) meets that pixel's centre ray (at most `max_gap_m` / 2 from
/// the hit's own depth), and the nearest surface wins. A pixel no hit lands on takes the nearer of
/// two opposite neighbours' depths (left and right, up and down, or diagonal) that agree within
/// `max_gap_m` (holes where the new view magnifies the surface); other pixels no hit lands on get
/// 0, and so do pixels that may show a surface through a gap in the warped foreground (a pixel
/// within one pixel of them holds a surface nearer by more than `max_gap_m`). The previous frame's
/// raycast warped this way gives the rays a second start hint, free of sensor noise (see
/// Raycaster::raycast).
/// `scratch` (optional): the images the warp keeps between calls.
void warp_raycast_depth(const RaycastResult& from, const PinholeCamera& camera, const Pose& T_wc,
                        float max_gap_m, DepthImage* out, WarpScratch* scratch = nullptr);

}  // namespace hivox

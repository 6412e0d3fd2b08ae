#pragma once
/// @file
/// Exact rendering of a synthetic scene through a pinhole camera: depth (z along the optical
/// axis, metres), Lambertian-shaded colour and world-frame normals, from analytic ray-primitive
/// intersections (no sampling error: a plane's or sphere's depth is exact to double rounding).

#include "hivox/core/camera.h"
#include "hivox/core/image.h"
#include "hivox/core/math.h"
#include "hivox/core/pose.h"
#include "hivox/synth/scene.h"

namespace hivox {

struct RenderedFrame {
  DepthImage depth_m;     ///< z distance along the optical axis, metres; 0 = no hit / too far
  ColorImage color;       ///< shaded colour; the scene's background colour where depth is 0
  Image<Vec3f> normal_w;  ///< unit surface normal in the world frame; zero where depth is 0
  Pose T_wc = Pose::Identity();  ///< the camera-to-world pose it was rendered from
};

/// Renders one frame. Rays go through pixel centres (integer pixel coordinates); pixels whose
/// first hit lies beyond `max_depth_m` (z distance) or that hit nothing get depth 0. Colour is
/// albedo x (ambient + (1 - ambient) max(0, n . to_light)) with the scene's fixed light. Rows
/// run in parallel (`parallel_for_dynamic`). Throws `Error(InvalidArgument)` for an invalid
/// camera or a non-positive `max_depth_m`.
RenderedFrame render(const SyntheticScene& scene, const PinholeCamera& camera, const Pose& T_wc,
                     double max_depth_m = 10.0);

}  // namespace hivox

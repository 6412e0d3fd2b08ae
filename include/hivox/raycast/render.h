#pragma once
/// @file
/// Turning raycast outputs into pictures for people: colour-mapped depth, normals, Phong
/// shading, fused colour and the refinement level of each surface point (paper Fig. 4).

#include "hivox/core/image.h"
#include "hivox/raycast/raycaster.h"

namespace hivox {

/// The nearest and farthest valid depth of an image (0 and 1 m when it has none; a range of at
/// least 1 mm), as `render_depth` maps them.
struct DepthExtent {
  float min_m = 0, max_m = 1;
};
DepthExtent depth_extent(const DepthImage& depth_m);

/// Depth colour-mapped from near (dark blue) to far (red); no hit is black.
/// `min_m`/`max_m` <= 0 pick the range of the image's valid depths (depth_extent).
ColorImage render_depth(const DepthImage& depth_m, float min_m = 0.0f, float max_m = 0.0f);

/// The colour of `render_depth` at `t` in [0, 1] between its nearest and farthest depth (for
/// scale bars).
Rgb8 depth_ramp_color(float t);

/// Camera-frame normals as RGB ((n + 1) / 2); no hit is black.
ColorImage render_normals(const RaycastResult& result);

/// Grey Phong shading with a light at the camera; no hit is black.
ColorImage render_shaded(const RaycastResult& result);

/// Fused surface colour, lightly shaded so that geometry stays visible; no hit is black.
ColorImage render_colors(const RaycastResult& result);

/// Refinement level of each surface point, shaded: finest red, then orange, green, blue for
/// coarser levels (as in the paper's Fig. 4). No hit is black.
ColorImage render_levels(const RaycastResult& result);

/// The colour used for `level` in `render_levels` (for legends).
Rgb8 level_color(int level);

}  // namespace hivox

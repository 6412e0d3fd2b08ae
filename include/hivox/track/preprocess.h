#pragma once
/// @file
/// Depth preprocessing for tracking: bilateral filter, depth pyramid, and per-pixel points and
/// normals in the camera frame computed from a depth image.

#include <vector>

#include "hivox/core/camera.h"
#include "hivox/core/camera_rig.h"
#include "hivox/core/image.h"
#include "hivox/core/math.h"
#include "hivox/track/params.h"

namespace hivox {

/// Edge-preserving smoothing: each valid pixel becomes the average of the valid depths in its
/// (2r+1)^2 window, weighted by a Gaussian of the pixel distance and of the depth difference.
/// Invalid pixels (0) stay invalid; depths outside `range` become invalid.
void bilateral_filter(const DepthImage& in, DepthImage& out, const TrackParams& params,
                      const DepthRange& range);

/// Halves the resolution: each output pixel averages the valid pixels of its 2x2 block whose
/// depth is near (within the jump ratio) the block's first valid one.
void downsample_depth(const DepthImage& in, DepthImage& out, const TrackParams& params);

/// Points (camera frame, metres) and unit normals (pointing to the camera) of a depth image; a
/// pixel without depth, at a border or across a depth discontinuity gets a zero normal.
void points_and_normals(const DepthImage& depth_m, const PinholeCamera& camera,
                        const TrackParams& params, Image<Vec3f>& points_c, Image<Vec3f>& normals_c);

/// One level of the frame pyramid.
struct PyramidLevel {
  PinholeCamera camera;
  DepthImage depth_m;
  Image<Vec3f> points_c;
  Image<Vec3f> normals_c;  ///< zero where there is no normal
};

/// Filters `depth_m` (depths outside `range` ignored) and builds `params.levels()` levels
/// (finest first) with points and normals.
void build_pyramid(const DepthImage& depth_m, const PinholeCamera& camera,
                   const TrackParams& params, const DepthRange& range,
                   std::vector<PyramidLevel>& levels);

}  // namespace hivox

#pragma once
/// @file
/// Raycasting the TSDF (DESIGN §5): one ray per pixel from a camera pose to the first surface.
/// Produces depth, world points and normals (the tracking input), colour and the level of the
/// block hit.

#include <cstdint>
#include <memory>
#include <vector>

#include "hivox/core/camera.h"
#include "hivox/core/camera_rig.h"
#include "hivox/core/image.h"
#include "hivox/core/math.h"
#include "hivox/core/pose.h"
#include "hivox/map/voxel_block_map.h"
#include "hivox/raycast/hints.h"
#include "hivox/raycast/params.h"

namespace hivox {

namespace kernels {
struct SurfaceTileStorage;
}

/// Per-pixel raycast outputs; a pixel without a hit has depth 0 and level -1.
struct RaycastResult {
  PinholeCamera camera;
  Pose T_wc = Pose::Identity();
  DepthImage depth_m;      ///< depth along the optical axis
  Image<Vec3f> points_w;   ///< surface points, world frame
  Image<Vec3f> normals_w;  ///< unit normals (pointing to free space), world frame
  ColorImage colors;       ///< fused colour at the hit (black without colour)
  Image<int8_t> levels;    ///< level of the block hit, -1 for no hit
  bool has_color = false;

  bool hit(int x, int y) const { return depth_m(x, y) > 0.0f; }
  /// Point and normal of pixel (x, y) in the camera frame.
  Vec3f point_c(int x, int y) const;
  Vec3f normal_c(int x, int y) const;
};

struct RaycastStats {
  int64_t blocks_projected = 0;   ///< blocks whose bounding box landed in the view
  int64_t hits = 0;               ///< pixels with a surface
  int64_t found_at_hint = 0;      ///< of them, found near a hint (without a march)
  int64_t found_at_fallback = 0;  ///< of those, found near the fallback hint
  double range_ms = 0;            ///< building the min/max depth range image
  double march_ms = 0;            ///< marching the rays
};

class Raycaster {
 public:
  explicit Raycaster(const RaycastParams& params = {});
  ~Raycaster();
  Raycaster(Raycaster&&) noexcept;
  Raycaster& operator=(Raycaster&&) noexcept;
  const RaycastParams& params() const { return params_; }

  /// Casts every pixel of `camera` from pose `T_wc` into `map`, over the depths of `range`
  /// (along the optical axis; rays start no nearer than 1 mm). The result is kept (and its
  /// buffers reused) until the next call.
  ///
  /// `hints.start_m` (optional, same size as the camera): a depth per pixel near which the
  /// surface is expected, e.g. the depth image just fused from this pose. A ray with a hint
  /// first looks for the surface at the hint itself (a sample there and a Newton step or two);
  /// failing that, it starts `hint_margin_mu` truncation bands before the hint instead of at the
  /// front of the depth range. Either way it skips the space in front (often many blocks for
  /// surfaces seen at grazing angles) but also any model surface the hint says is not there.
  /// Pixels without a hint (0) search the whole range.
  ///
  /// `hints.fallback_m` (optional, same size): a second depth per pixel, searched the same way
  /// where `start_m` has none, or where the search at it fails, before the ray marches: e.g.
  /// the previous frame's raycast warped into this view (warp_raycast_depth) where the start
  /// hint is the depth just measured. Where that depth is missing or disagrees with the model (it
  /// lies in front of the model's surface, or on voxels not yet observed), the model's surface is
  /// usually where the previous frame saw it. Where the two hints agree (within
  /// `hint_agreement_mu` truncation bands), the fallback is searched first and the start hint
  /// second: the measured depth says which surface, the previous raycast where the model holds it
  /// (the measured depth is off by the sensor's noise, often more than a voxel).
  const RaycastResult& raycast(const VoxelBlockMap& map, const PinholeCamera& camera,
                               const Pose& T_wc, const DepthRange& range,
                               const RaycastHints& hints = {}, RaycastStats* stats = nullptr);
  const RaycastResult& result() const { return result_; }

 private:
  /// The CPU's raycast into result_ (camera and pose set): range tiles, the coarse occupancy
  /// and surface tiles, then the tile driver (src/raycast/cpu/tile_driver.h).
  void raycast_cpu(const VoxelBlockMap& map, const DepthRange& range, const RaycastHints& hints,
                   RaycastStats& stats);

  RaycastParams params_;
  RaycastResult result_;
  std::vector<float> tile_min_, tile_max_;
  std::vector<int32_t> occupancy_;  ///< which super-blocks hold blocks (see coarse_skipping)
  std::unique_ptr<kernels::SurfaceTileStorage> surface_tiles_;  ///< see surface_tiles
};

}  // namespace hivox

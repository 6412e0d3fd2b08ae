#pragma once
// The range tiles' CPU passes over the map's blocks: their depth ranges (fill_range_tiles) and,
// per tile, the boxes around the blocks that hold a surface: a marching ray tests its tile's
// boxes and marches only over the stretch they span (none: no surface on the ray). The view and
// its ray test are written once for the CPU and CUDA drivers; the lists are filled on the CPU
// (build_surface_tiles).

#include <cstdint>
#include <vector>

#include "hivox/core/camera.h"
#include "hivox/core/hd.h"
#include "hivox/core/math.h"
#include "hivox/map/map_view.h"
#include "raycast/raycast_kernels.h"

namespace hivox {
class VoxelBlockMap;
}

namespace hivox::kernels {

/// A ray can only meet a surface (an interpolated TSDF <= 0) in a cell with an observed corner
/// <= 0, and every such corner lies in a block whose BlockSurface has a surface bit. A sample is
/// interpolated from corners at most one voxel of the coarsest level away on each axis, so each
/// such block's box, grown by that voxel, holds every point where a ray can meet a surface.
/// These boxes, listed per range tile (the tiles their projection covers, as the range image
/// projects blocks), relative to the camera centre, structure of arrays.
struct SurfaceTiles {
  const int32_t* begin = nullptr;  ///< tile t's boxes are [begin[t], begin[t + 1])
  const float* lo[3] = {};         ///< box corners minus the camera centre, per axis
  const float* hi[3] = {};

  HIVOX_HD bool empty() const { return begin == nullptr; }

  /// The stretch [*z_in, *z_out] of ray `o + z d` (o the camera centre, `inv_d` from
  /// inverse_direction) within (z_min, z_max) that crosses the boxes of tile `tile`; false when it
  /// crosses none, so that no surface lies on the ray there. The stretch is the first entry to
  /// the last exit: the space between two boxes is surface-free but included.
  HIVOX_HD bool ray_stretch(int tile, const Vec3f& inv_d, float z_min, float z_max, float* z_in,
                            float* z_out) const {
    float first = FLT_MAX, last = -FLT_MAX;
    const int32_t b0 = begin[tile], b1 = begin[tile + 1];
    const float ix = inv_d.x, iy = inv_d.y, iz = inv_d.z;
    const float *lx = lo[0], *ly = lo[1], *lz = lo[2], *hx = hi[0], *hy = hi[1], *hz = hi[2];
#if !defined(__CUDA_ARCH__)
#pragma omp simd reduction(min : first) reduction(max : last)
#endif
    for (int32_t b = b0; b < b1; ++b) {
      // Slabs per axis (ternaries, not fminf / fmaxf: those are calls unless NaNs are ruled out).
      const float ax = lx[b] * ix, bx = hx[b] * ix;
      const float ay = ly[b] * iy, by = hy[b] * iy;
      const float az = lz[b] * iz, bz = hz[b] * iz;
      const float in_x = ax < bx ? ax : bx, out_x = ax < bx ? bx : ax;
      const float in_y = ay < by ? ay : by, out_y = ay < by ? by : ay;
      const float in_z = az < bz ? az : bz, out_z = az < bz ? bz : az;
      float t_in = in_x > in_y ? in_x : in_y;
      t_in = in_z > t_in ? in_z : t_in;
      t_in = z_min > t_in ? z_min : t_in;
      float t_out = out_x < out_y ? out_x : out_y;
      t_out = out_z < t_out ? out_z : t_out;
      t_out = z_max < t_out ? z_max : t_out;
      const bool crossed = t_in <= t_out;
      first = crossed && t_in < first ? t_in : first;
      last = crossed && t_out > last ? t_out : last;
    }
    *z_in = first;
    *z_out = last;
    return first <= last;
  }
};

/// The storage behind a SurfaceTiles view.
struct SurfaceTileStorage {
  std::vector<int32_t> begin;
  std::vector<float> boxes;     ///< six arrays of `boxes.size() / 6` floats: lo x, y, z, hi x, y, z
  std::vector<int32_t> rects;   ///< per block: its tile rectangle (tx0, ty0, tx1, ty1), scratch
  std::vector<int32_t> cursor;  ///< per tile: the next free slot while filling, scratch
};

/// The range image: every block of `map` projected into the tiles of `tiles` it covers, seen by
/// `camera` from `T_cw` (the depth range of each tile widened to its blocks' within [min_depth_m,
/// max_depth_m]; `tiles.z_min` and `z_max` must be set to FLT_MAX and 0 first). Returns the
/// number of blocks in view.
int64_t fill_range_tiles(const VoxelBlockMap& map, const PinholeCamera& camera, const Rigid3f& T_cw,
                         float min_depth_m, float max_depth_m, const RangeTiles& tiles);

/// Lists the boxes (see SurfaceTiles) of every block of `map` with a surface, seen by `camera`
/// from `T_cw`, in the tiles of `tiles` (whose depth ranges are not touched) their projection
/// covers within [min_depth_m, max_depth_m]. The view is valid while `storage` is unchanged.
SurfaceTiles build_surface_tiles(const VoxelBlockMap& map, const PinholeCamera& camera,
                                 const Rigid3f& T_cw, const Vec3f& camera_centre_w,
                                 const RangeTiles& tiles, float min_depth_m, float max_depth_m,
                                 SurfaceTileStorage* storage);

}  // namespace hivox::kernels

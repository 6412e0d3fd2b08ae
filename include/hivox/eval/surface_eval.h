#pragma once
/// @file
/// Accuracy of a reconstruction at reference surface points (DESIGN §8, paper Table I): the
/// reconstruction's TSDF, interpolated across levels, at points sampled on a reference surface
/// is their distance to the reconstructed surface.

#include <cstdint>
#include <span>
#include <vector>

#include "hivox/core/math.h"
#include "hivox/map/voxel_block_map.h"

namespace hivox {

struct PointEval {
  float distance_m = 0.0f;  ///< |TSDF| * truncation at the point (valid when `found`)
  int level = -1;           ///< level of the block storing the point, -1 when none does
  bool found = false;       ///< the point lies in observed space (TSDF interpolated)
};

struct SurfaceEval {
  int64_t points = 0;
  int64_t found = 0;                      ///< points with an interpolated TSDF
  double mean_distance_m = 0;             ///< over found points
  std::vector<int64_t> points_per_level;  ///< points stored at each level (finest first)
  std::vector<PointEval> per_point;       ///< in input order
};

/// Evaluates the map at reference surface points `points_w` (distances in metres through the
/// map's truncation band). Voxels observed fewer than `min_weight` (>= 1) times count as unknown.
SurfaceEval evaluate_at_points(const VoxelBlockMap& map, std::span<const Vec3f> points_w,
                               int min_weight = 1);

}  // namespace hivox

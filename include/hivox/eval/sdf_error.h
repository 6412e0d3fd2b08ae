#pragma once
/// @file
/// The paper's Table I protocol (`hivox eval sdf-error`): points sampled uniformly by area on the
/// mesh of a reference reconstruction (the fixed finest grid), and the mean |SDF| of other
/// reconstructions of the same sequence and poses at those points. A map whose surface lies
/// exactly where the reference's does scores 0; the score grows with the distance between the
/// surfaces (up to the truncation band, where the TSDF saturates).

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "hivox/core/math.h"
#include "hivox/map/voxel_block_map.h"
#include "hivox/mesh/triangle_mesh.h"

namespace hivox {

struct SdfErrorParams {
  int64_t samples = 1'000'000;  ///< points sampled on the reference mesh (the paper used 20 M)
  uint64_t seed = 1;            ///< of the sampling
  int min_weight = 1;           ///< voxels observed fewer times count as unknown

  /// Throws `Error(InvalidArgument)` naming the bad setting.
  void validate() const;
  std::string to_string() const;
};

/// One map's score at the sampled points.
struct MapSdfError {
  std::string name;
  int64_t found = 0;          ///< points where the map has an interpolated TSDF
  double coverage = 0;        ///< found / samples
  double mean_abs_sdf_m = 0;  ///< mean |SDF| over the found points, metres
  double median_abs_sdf_m = 0;
  double rmse_m = 0;
  /// Per level of the map (finest first): points stored there, their mean |SDF| (0 when none).
  std::vector<int64_t> points_per_level;
  std::vector<double> mean_abs_sdf_per_level_m;
};

struct SdfErrorResult {
  int64_t samples = 0;            ///< points sampled on the reference mesh
  std::vector<Vec3f> points_w;    ///< the sampled points
  std::vector<MapSdfError> maps;  ///< in the order given
  /// Per map, per point: |SDF| in metres, or a negative value where the map has none.
  std::vector<std::vector<float>> per_point_m;
};

/// A map to score and its name in the results.
struct NamedMap {
  std::string name;
  const VoxelBlockMap* map = nullptr;
};

/// Samples `params.samples` points on `reference` (uniformly by area, `sample_surface`) and
/// scores each map at them. Throws `Error(InvalidArgument)` for a reference without a triangle of
/// positive area, a null map or bad params.
SdfErrorResult evaluate_sdf_error(const TriangleMesh& reference, std::span<const NamedMap> maps,
                                  const SdfErrorParams& params = {});

/// Scores one map at given points (the part of `evaluate_sdf_error` after the sampling), filling
/// `per_point_m` when it is not null.
MapSdfError score_map(const VoxelBlockMap& map, std::span<const Vec3f> points_w, int min_weight = 1,
                      std::vector<float>* per_point_m = nullptr);

}  // namespace hivox

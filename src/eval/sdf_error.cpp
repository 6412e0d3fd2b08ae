#include "hivox/eval/sdf_error.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "hivox/core/error.h"
#include "hivox/eval/mesh_eval.h"
#include "hivox/eval/surface_eval.h"

namespace hivox {

void SdfErrorParams::validate() const {
  if (samples < 1 || samples > 100'000'000)
    fail(ErrorCode::InvalidArgument, "sdf-error: samples must be in 1..1e8, got {}", samples);
  if (min_weight < 1)
    fail(ErrorCode::InvalidArgument,
         "sdf-error: min_weight must be >= 1 (0 would count unobserved voxels), got {}",
         min_weight);
}

std::string SdfErrorParams::to_string() const {
  return fmt::format("samples {}, seed {}, min weight {}", samples, seed, min_weight);
}

MapSdfError score_map(const VoxelBlockMap& map, std::span<const Vec3f> points_w, int min_weight,
                      std::vector<float>* per_point_m) {
  const SurfaceEval e = evaluate_at_points(map, points_w, min_weight);
  MapSdfError out;
  out.found = e.found;
  out.coverage = e.points > 0 ? static_cast<double>(e.found) / static_cast<double>(e.points) : 0.0;
  out.mean_abs_sdf_m = e.mean_distance_m;
  const std::size_t levels = static_cast<std::size_t>(map.levels());
  out.points_per_level = e.points_per_level;
  out.mean_abs_sdf_per_level_m.assign(levels, 0.0);
  std::vector<int64_t> found_per_level(levels, 0);
  std::vector<float> found;
  found.reserve(static_cast<std::size_t>(e.found));
  double sum_sq = 0;
  if (per_point_m) per_point_m->assign(points_w.size(), -1.0f);
  for (std::size_t i = 0; i < e.per_point.size(); ++i) {
    const PointEval& p = e.per_point[i];
    if (!p.found) continue;
    found.push_back(p.distance_m);
    sum_sq += static_cast<double>(p.distance_m) * p.distance_m;
    if (per_point_m) (*per_point_m)[i] = p.distance_m;
    if (p.level >= 0) {
      out.mean_abs_sdf_per_level_m[static_cast<std::size_t>(p.level)] += p.distance_m;
      ++found_per_level[static_cast<std::size_t>(p.level)];
    }
  }
  for (std::size_t l = 0; l < levels; ++l)
    out.mean_abs_sdf_per_level_m[l] =
        found_per_level[l] > 0
            ? out.mean_abs_sdf_per_level_m[l] / static_cast<double>(found_per_level[l])
            : 0.0;
  if (!found.empty()) {
    const auto mid = found.begin() + static_cast<std::ptrdiff_t>(found.size() / 2);
    std::nth_element(found.begin(), mid, found.end());
    out.median_abs_sdf_m = *mid;
    out.rmse_m = std::sqrt(sum_sq / static_cast<double>(found.size()));
  }
  return out;
}

SdfErrorResult evaluate_sdf_error(const TriangleMesh& reference, std::span<const NamedMap> maps,
                                  const SdfErrorParams& params) {
  params.validate();
  for (const NamedMap& m : maps)
    if (m.map == nullptr) fail(ErrorCode::InvalidArgument, "sdf-error: map '{}' is null", m.name);
  SdfErrorResult out;
  out.points_w = sample_surface(reference, params.samples, params.seed);
  out.samples = static_cast<int64_t>(out.points_w.size());
  out.per_point_m.resize(maps.size());
  for (std::size_t i = 0; i < maps.size(); ++i) {
    out.maps.push_back(
        score_map(*maps[i].map, out.points_w, params.min_weight, &out.per_point_m[i]));
    out.maps.back().name = maps[i].name;
  }
  return out;
}

}  // namespace hivox

#include "hivox/eval/surface_eval.h"

#include "core/parallel.h"
#include "hivox/core/error.h"
#include "map/sample_kernels.h"

namespace hivox {

SurfaceEval evaluate_at_points(const VoxelBlockMap& map, std::span<const Vec3f> points_w,
                               int min_weight) {
  if (min_weight < 1)
    fail(ErrorCode::InvalidArgument,
         "evaluate_at_points: min_weight must be >= 1 (0 would count unobserved voxels), got {}",
         min_weight);
  const float truncation_m = map.params().truncation_m;
  SurfaceEval out;
  out.points = static_cast<int64_t>(points_w.size());
  out.per_point.resize(points_w.size());
  out.points_per_level.assign(static_cast<std::size_t>(map.levels()), 0);
  const MapView view = map.view();
  parallel_team([&](const ThreadTeam& team) {
    kernels::BlockLookupCache cache;  // per thread
    team.for_each(
        static_cast<int64_t>(points_w.size()),
        [&](int64_t i) {
          PointEval& e = out.per_point[static_cast<std::size_t>(i)];
          int level;
          Vec3i pos;
          if (kernels::locate_block(view, cache, points_w[i], &level, &pos) < 0) return;
          e.level = level;
          kernels::TsdfSample s;
          int l2;
          if (!kernels::sample_tsdf(view, cache, points_w[i], min_weight, &s, &l2)) return;
          e.found = true;
          e.distance_m = std::abs(s.f) * truncation_m;
        },
        CpuSchedule::dynamic(1024));
  });
  double sum = 0.0;
  for (const PointEval& e : out.per_point) {
    if (e.level >= 0) ++out.points_per_level[static_cast<std::size_t>(e.level)];
    if (!e.found) continue;
    ++out.found;
    sum += e.distance_m;
  }
  out.mean_distance_m = out.found > 0 ? sum / static_cast<double>(out.found) : 0.0;
  return out;
}

}  // namespace hivox

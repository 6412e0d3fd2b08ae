#include "hivox/refine/refiner.h"

#include <algorithm>
#include <array>

#include "core/parallel.h"
#include "hivox/core/error.h"
#include "hivox/core/log.h"
#include "hivox/map/hierarchy_edit.h"
#include "map/hierarchy_kernels.h"
#include "refine/refine_kernels.h"

namespace hivox {

Refiner::Refiner(const RefineParams& params, const SensorNoise& sensor_noise)
    : params_(params), noise_(params.noise.value_or(sensor_noise)) {
  params_.validate();
}

float Refiner::complexity(const VoxelBlockMap& map, int32_t ptr, float* mean_weight) const {
  const TsdfVoxel* v = map.block_tsdf(ptr);
  switch (params_.criterion) {
    case RefineCriterion::Detail:
      return kernels::block_detail_m(v, map.params().truncation_m, params_.min_weight,
                                     params_.min_samples, mean_weight);
    case RefineCriterion::DetCov:
      return kernels::block_det_cov(v, params_.min_weight);
  }
  return -1.0f;
}

RefineStats Refiner::refine(VoxelBlockMap& map, std::span<const BlockRef> candidates,
                            const Pose& T_wc) {
  if (map.levels() < 2 || (calls_++ % params_.every_n_frames) != 0) return {};
  return dispatch(map.device(), "refinement", [&] { return refine_cpu(map, candidates, T_wc); });
}

RefineStats Refiner::refine_cpu(VoxelBlockMap& map, std::span<const BlockRef> candidates,
                                const Pose& T_wc) {
  RefineStats stats;
  const MapView view = map.view();
  const int top = view.levels - 1;
  auto settled = [&](int32_t ptr) { return view.meta[ptr].updates >= params_.min_updates; };
  // Depth of a block's centre from the camera that just saw it (for the noise model).
  const Rigid3f T_cw = to_rigid3f(T_wc.inverse());
  auto depth_of = [&](const Vec3i& pos, int level) {
    const float b = view.level[level].block_size_m;
    const Vec3f centre{(pos.x + 0.5f) * b, (pos.y + 0.5f) * b, (pos.z + 0.5f) * b};
    return (T_cw * centre).z;
  };

  // Split candidates: settled blocks above the finest level with complex surface, or with
  // surface their level cannot mesh.
  std::vector<uint8_t> split(candidates.size(), 0);
  parallel_for(static_cast<int64_t>(candidates.size()), [&](int64_t i) {
    const BlockRef& b = candidates[static_cast<std::size_t>(i)];
    if (b.ptr < 0 || b.level == 0 || !settled(b.ptr)) return;
    float w = 0.0f;
    const float c = complexity(map, b.ptr, &w);
    split[i] =
        c > params_.split_level(noise_, depth_of(b.pos, b.level), w) ||
        (params_.split_unmeshable_cells > 0 &&
         kernels::block_unmeshable_cells(map.block_tsdf(b.ptr), params_.unmeshable_min_weight) >=
             params_.split_unmeshable_cells);
  });
  std::vector<BlockRef> splits;
  for (std::size_t i = 0; i < candidates.size(); ++i)
    if (split[i]) splits.push_back(candidates[i]);
  stats.evaluated = static_cast<int64_t>(candidates.size());

  // Merge candidates: the split parents of touched blocks below the coarsest level, when all 8
  // children are settled leaves with simple surface.
  std::vector<BlockKey> parents;
  for (const BlockRef& b : candidates)
    if (b.level < top) parents.push_back({parent_block_pos(b.pos), b.level + 1});
  std::sort(parents.begin(), parents.end());
  parents.erase(std::unique(parents.begin(), parents.end()), parents.end());
  std::vector<uint8_t> mergeable(parents.size(), 0);
  parallel_for(static_cast<int64_t>(parents.size()), [&](int64_t i) {
    const BlockKey& p = parents[static_cast<std::size_t>(i)];
    if (find_block_ptr(view.level[p.level], p.pos) != kPtrSplit) return;
    const float level = params_.merge_level(noise_, depth_of(p.pos, p.level));
    int32_t children[kBlockChildren];
    for (int k = 0; k < kBlockChildren; ++k) {
      const int32_t ptr = find_block_ptr(view.level[p.level - 1], child_block_pos(p.pos, k));
      if (ptr < 0) return;
      children[k] = ptr;
      const float c = complexity(map, ptr);
      // A child with too little surface to judge holds nothing a merge could lose, however
      // young: the children of a table top's block that lie below the band seen from above are
      // never integrated, and waiting for them to settle kept the flat top split for good.
      if (c < 0.0f) continue;
      if (!settled(ptr) || c >= level) return;
    }
    if (params_.split_unmeshable_cells > 0) {
      // The parent the merge would make (the map's subsampling) must mesh its surface.
      TsdfVoxel merged[kBlockVoxels];
      for (int j = 0; j < kBlockVoxels; ++j) {
        int k;
        const int src = kernels::merged_voxel_source(j, &k);
        merged[j] = map.block_tsdf(children[k])[src];
      }
      if (kernels::block_unmeshable_cells(merged, params_.unmeshable_min_weight) >=
          params_.split_unmeshable_cells)
        return;
    }
    mergeable[i] = 1;
  });
  std::vector<BlockKey> merges;
  for (std::size_t i = 0; i < parents.size(); ++i)
    if (mergeable[i]) merges.push_back(parents[i]);
  stats.evaluated += static_cast<int64_t>(parents.size());

  const SplitMergeResult m = merge_blocks(map, merges);
  const SplitMergeResult s = split_blocks(map, splits, params_.split_weight_scale);
  stats.merges = m.done;
  stats.splits = s.done;
  stats.waiting = m.waiting + s.waiting;
  return stats;
}

}  // namespace hivox

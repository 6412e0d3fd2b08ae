// Refinement on the device: the CPU Refiner's per-block decisions and the map's split and merge
// passes (src/refine/refiner.cpp, src/map/hierarchy_edit.cpp), from the same kernels.

#include <cuda_runtime.h>

#include "core/parallel.h"
#include "cuda/device_helpers.cuh"
#include "cuda/loop_kernels.h"
#include "hivox/map/hierarchy_edit.h"
#include "map/hierarchy_kernels.h"
#include "map/map_kernels.h"

namespace hivox::cuda {

namespace {

constexpr int kThreads = 128;

unsigned grid_for(int64_t n) {
  const int64_t blocks = (n + kThreads - 1) / kThreads;
  return static_cast<unsigned>(blocks < 1 ? 1 : blocks);
}

__device__ float depth_of(const RefineConstants& k, const MapView& map, const Vec3i& pos,
                          int level) {
  const float b = map.level[level].block_size_m;
  const Vec3f centre{(pos.x + 0.5f) * b, (pos.y + 0.5f) * b, (pos.z + 0.5f) * b};
  return (k.T_cw * centre).z;
}

constexpr unsigned kFullWarp = 0xFFFFFFFFu;

/// The sum of `x` over the warp by a butterfly of xor shuffles. Every lane ends with the same
/// value: at each step the two lanes of a pair add the same two numbers.
template <typename T>
__device__ T warp_sum(T x) {
  for (int o = 16; o > 0; o >>= 1) x += __shfl_xor_sync(kFullWarp, x, o);
  return x;
}

/// The block's complexity by one whole warp: the detail criterion's samples
/// (kernels::detail_sample) shared out among the lanes and summed; the DetCov criterion on lane
/// 0 alone. Every lane gets the same value.
__device__ float warp_complexity(const RefineConstants& k, const TsdfVoxel* v, float* mean_weight) {
  const int lane = static_cast<int>(threadIdx.x & 31);
  if (k.det_cov) {
    const float c = lane == 0 ? kernels::block_det_cov(v, k.min_weight) : 0.0f;
    return __shfl_sync(kFullWarp, c, 0);
  }
  float sum = 0.0f, weights = 0.0f;
  int n = 0;
  for (int axis = 0; axis < 3; ++axis)
    for (int i = lane; i < kBlockVoxels; i += 32) {
      float d2, w;
      if (!kernels::detail_sample(v, axis, i, k.min_weight, &d2, &w)) continue;
      sum += d2;
      weights += w;
      ++n;
    }
  return kernels::detail_from_sums(warp_sum(sum), warp_sum(weights), warp_sum(n), k.mu_m,
                                   k.min_samples, mean_weight);
}

/// kernels::block_unmeshable_cells by one whole warp (the 7^3 cells shared out).
__device__ int warp_unmeshable_cells(const TsdfVoxel* v, int min_weight) {
  constexpr int kInner = kBlockSide - 1;
  int n = 0;
  for (int cell = static_cast<int>(threadIdx.x & 31); cell < kInner * kInner * kInner; cell += 32)
    n += kernels::unmeshable_cell(v, cell % kInner, (cell / kInner) % kInner,
                                  cell / (kInner * kInner), min_weight);
  return warp_sum(n);
}

constexpr int kWarpsPerBlock = kThreads / 32;

/// One warp per visible block: the CPU Refiner's split test, and the block's parent into the
/// set of merge candidates.
__global__ void __launch_bounds__(kThreads)
    split_candidates_kernel(MapView map, const BlockRef* visible, const AllocCounters* counters,
                            RefineConstants k, RefineLists lists) {
  const int32_t i = blockIdx.x * kWarpsPerBlock + static_cast<int32_t>(threadIdx.x / 32);
  const bool lead = (threadIdx.x & 31) == 0;
  if (i >= counters->visible) return;  // the whole warp
  const BlockRef b = visible[i];
  if (lead && b.level < map.levels - 1)
    add_unique(lists.parents, b.level + 1, parent_block_pos(b.pos), &lists.counts[1]);
  if (b.ptr < 0 || b.level == 0 || map.meta[b.ptr].updates < k.min_updates) return;
  const TsdfVoxel* v = map.tsdf + static_cast<int64_t>(b.ptr) * kBlockVoxels;
  float w = 0.0f;
  const float c = warp_complexity(k, v, &w);
  const float level =
      kernels::split_level(k.levels, k.noise.sigma_m(depth_of(k, map, b.pos, b.level)), w);
  const bool split =
      c > level || (k.unmeshable_cells > 0 &&
                    warp_unmeshable_cells(v, k.unmeshable_min_weight) >= k.unmeshable_cells);
  if (!split || !lead) return;
  const int32_t slot = atomicAdd(&lists.counts[0], 1);
  if (slot < lists.capacity) lists.splits[slot] = b;
}

/// One CUDA block per parent, one warp per child: each warp judges its child, then the first
/// warp decides (the CPU Refiner's merge test), checking the merged block on voxels the whole
/// block gathered. The grid is a bound: the blocks past the parents' count, read here, return.
__global__ void __launch_bounds__(kBlockChildren * 32)
    merge_candidates_kernel(MapView map, RefineConstants k, RefineLists lists) {
  const int32_t i = blockIdx.x;
  const int c = static_cast<int>(threadIdx.x / 32);
  __shared__ int32_t children[kBlockChildren];
  __shared__ int32_t verdict[kBlockChildren];
  __shared__ TsdfVoxel merged[kBlockVoxels];
  if (i >= lists.counts[1] || i >= lists.parents.capacity) return;  // the whole block
  const BlockKey p = lists.parents.list[i];
  if (find_block_ptr(map.level[p.level], p.pos) != kPtrSplit) return;  // the whole block
  const int32_t ptr = find_block_ptr(map.level[p.level - 1], child_block_pos(p.pos, c));
  bool ok = false;
  if (ptr >= 0) {
    const float level =
        kernels::merge_level(k.levels, k.noise.sigma_m(depth_of(k, map, p.pos, p.level)));
    float w = 0.0f;
    const float x = warp_complexity(k, map.tsdf + static_cast<int64_t>(ptr) * kBlockVoxels, &w);
    // A child with too little surface to judge holds nothing a merge could lose (see the CPU's).
    ok = x < 0.0f || (map.meta[ptr].updates >= k.min_updates && x < level);
  }
  if ((threadIdx.x & 31) == 0) {
    children[c] = ptr;
    verdict[c] = ok;
  }
  __syncthreads();
  for (int j = 0; j < kBlockChildren; ++j)
    if (!verdict[j]) return;  // the whole block
  if (k.unmeshable_cells > 0) {
    // The parent the merge would make must mesh its surface.
    for (int j = threadIdx.x; j < kBlockVoxels; j += blockDim.x) {
      int from;
      const int src = kernels::merged_voxel_source(j, &from);
      merged[j] = map.tsdf[static_cast<int64_t>(children[from]) * kBlockVoxels + src];
    }
    __syncthreads();
    if (c != 0) return;
    if (warp_unmeshable_cells(merged, k.unmeshable_min_weight) >= k.unmeshable_cells) return;
  } else if (c != 0) {
    return;
  }
  if ((threadIdx.x & 31) != 0) return;
  const int32_t slot = atomicAdd(&lists.counts[2], 1);
  if (slot < lists.capacity) lists.merges[slot] = p;
}

__global__ void merge_lookup_kernel(MapView map, MergeJob* jobs, int32_t n, int32_t* ok_count) {
  const int32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  MergeJob& m = jobs[i];
  const BlockKey k = m.parent;
  bool ok = k.level > 0 && k.level < map.levels;
  if (ok) {
    m.entry = find_entry(map.level[k.level], k.pos);
    ok = m.entry != kNoEntry && map.level[k.level].entries[m.entry].ptr == kPtrSplit;
  }
  for (int c = 0; ok && c < kBlockChildren; ++c) {
    const LevelView& lv = map.level[k.level - 1];
    m.child_entry[c] = find_entry(lv, child_block_pos(k.pos, c));
    ok = m.child_entry[c] != kNoEntry && lv.entries[m.child_entry[c]].ptr >= 0;
    if (ok) m.child_block[c] = lv.entries[m.child_entry[c]].ptr;
  }
  m.ok = ok;
  if (ok && ok_count != nullptr) atomicAdd(ok_count, 1);
}

/// One CUDA block per merge, one thread per voxel: the first thread takes the parent's block,
/// then every thread copies its voxel from its child (kernels::merged_voxel_source, as
/// kernels::fill_merged_parent does).
__global__ void __launch_bounds__(kBlockVoxels)
    merge_fill_kernel(MutableMapView map, MergeJob* jobs) {
  MergeJob& m = jobs[blockIdx.x];
  if (m.ok == 0) return;  // the whole CUDA block
  __shared__ int32_t block;
  __shared__ SharedSurface summary;
  if (threadIdx.x == 0) {
    block = kernels::take_block(map);
    m.block = block;
    summary.clear();
  }
  __syncthreads();
  const int i = threadIdx.x;
  int child;
  const int src = kernels::merged_voxel_source(i, &child);
  const int64_t at = static_cast<int64_t>(m.child_block[child]) * kBlockVoxels + src;
  const int64_t to = static_cast<int64_t>(block) * kBlockVoxels + i;
  const TsdfVoxel v = map.tsdf[at];
  map.tsdf[to] = v;
  if (map.color != nullptr) map.color[to] = map.color[at];
  summary.add(i, v.weight, v.tsdf);
  __syncthreads();
  if (threadIdx.x == 0) m.surface = summary.get();
}

__global__ void merge_publish_kernel(MutableMapView map, MergeJob* jobs, int32_t n) {
  const int32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n || jobs[i].ok == 0) return;
  MergeJob& m = jobs[i];
  const int pl = m.parent.level;
  map.meta[m.block] = BlockMeta{m.parent.pos, m.entry, static_cast<int16_t>(pl), 0, m.surface};
  atomic_store(&map.level[pl].entries[m.entry].ptr, m.block);
  const MutableLevelView& lv = map.level[pl - 1];
  for (int c = 0; c < kBlockChildren; ++c) {
    atomic_store(&lv.entries[m.child_entry[c]].ptr, kPtrEmpty);
    const bool gone =
        kernels::unlink_tail_entry(map, pl - 1, m.child_entry[c], child_block_pos(m.parent.pos, c));
    // The unlinked entry goes back below (pushes only in that pass).
    if (!gone) m.child_entry[c] = kNoEntry;
  }
}

__global__ void merge_return_kernel(MutableMapView map, const MergeJob* jobs, int32_t n) {
  const int32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n || jobs[i].ok == 0) return;
  const MergeJob& m = jobs[i];
  for (int c = 0; c < kBlockChildren; ++c) {
    kernels::return_block(map, m.child_block[c]);
    if (m.child_entry[c] != kNoEntry)
      kernels::free_list_push(map.level[m.parent.level - 1].excess, m.child_entry[c]);
  }
  atomicAdd(&map.level_block_count[m.parent.level], 1);
  atomicAdd(&map.level_block_count[m.parent.level - 1], -kBlockChildren);
}

__global__ void split_check_kernel(MapView map, SplitJob* jobs, int32_t n, int32_t* ok_count) {
  const int32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  SplitJob& s = jobs[i];
  const BlockRef& b = s.parent;
  s.ok = b.level > 0 && b.level < map.levels && b.entry >= 0 && b.ptr >= 0 &&
         map.level[b.level].entries[b.entry].ptr == b.ptr &&
         map.level[b.level].entries[b.entry].pos == b.pos;
  if (s.ok != 0 && ok_count != nullptr) atomicAdd(ok_count, 1);
}

__global__ void split_sources_kernel(MapView map, SplitJob* jobs, int32_t n) {
  const int32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n || jobs[i].ok == 0) return;
  SplitJob& s = jobs[i];
  kernels::split_sources(map, s.parent, s.parents, s.neighbour_children);
}

/// One CUDA block per child, one thread per voxel: the first thread claims the child's entry
/// and block, then every thread fills its voxel (kernels::split_child_voxel).
__global__ void __launch_bounds__(kBlockVoxels)
    split_fill_kernel(MutableMapView map, SplitJob* jobs, float weight_scale) {
  SplitJob& s = jobs[blockIdx.x / kBlockChildren];
  if (s.ok == 0) return;  // the whole CUDA block
  const int c = static_cast<int>(blockIdx.x % kBlockChildren);
  const BlockRef& p = s.parent;
  __shared__ int32_t block;
  __shared__ SharedSurface summary;
  if (threadIdx.x == 0) {
    s.child_entry[c] = kernels::reserve_entry(map, p.level - 1, child_block_pos(p.pos, c));
    block = kernels::take_block(map);
    s.child_block[c] = block;
    summary.clear();
  }
  __syncthreads();
  const int i = threadIdx.x;
  ColorVoxel color;
  const TsdfVoxel v =
      kernels::split_child_voxel(map, p, s.parents, s.neighbour_children, c, i, weight_scale,
                                 map.color != nullptr ? &color : nullptr);
  map.tsdf[static_cast<int64_t>(block) * kBlockVoxels + i] = v;
  if (map.color != nullptr) map.color[static_cast<int64_t>(block) * kBlockVoxels + i] = color;
  summary.add(i, v.weight, v.tsdf);
  __syncthreads();
  if (threadIdx.x == 0) s.child_surface[c] = summary.get();
}

__global__ void split_publish_kernel(MutableMapView map, SplitJob* jobs, int32_t n) {
  const int32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n || jobs[i].ok == 0) return;
  const SplitJob& s = jobs[i];
  const BlockRef& p = s.parent;
  const MutableLevelView& child_level = map.level[p.level - 1];
  for (int c = 0; c < kBlockChildren; ++c) {
    const int32_t b = s.child_block[c];
    map.meta[b] = BlockMeta{child_block_pos(p.pos, c), s.child_entry[c],
                            static_cast<int16_t>(p.level - 1), 0, s.child_surface[c]};
    atomic_store(&child_level.entries[s.child_entry[c]].ptr, b);
  }
  atomic_store(&map.level[p.level].entries[p.entry].ptr, kPtrSplit);
}

__global__ void split_finish_kernel(MutableMapView map, const SplitJob* jobs, int32_t n) {
  const int32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n || jobs[i].ok == 0) return;
  const BlockRef& p = jobs[i].parent;
  kernels::return_block(map, p.ptr);
  atomicAdd(&map.level_block_count[p.level], -1);
  atomicAdd(&map.level_block_count[p.level - 1], kBlockChildren);
}

}  // namespace

void split_candidates(const MapView& map, const BlockRef* visible, int32_t max_visible,
                      const AllocCounters* counters, const RefineConstants& k,
                      const RefineLists& lists) {
  if (max_visible <= 0) return;
  const auto blocks = static_cast<unsigned>((max_visible + kWarpsPerBlock - 1) / kWarpsPerBlock);
  launch(split_candidates_kernel, blocks, kThreads, map, visible, counters, k, lists);
  check_last("refinement (split candidates)");
}

void merge_candidates(const MapView& map, int32_t max_parents, const RefineConstants& k,
                      const RefineLists& lists) {
  if (max_parents <= 0) return;
  launch(merge_candidates_kernel, static_cast<unsigned>(max_parents), kBlockChildren * 32, map, k,
         lists);
  check_last("refinement (merge candidates)");
}

void merge_lookup(const MapView& map, MergeJob* jobs, int32_t n, int32_t* ok_count) {
  if (n <= 0) return;
  launch(merge_lookup_kernel, grid_for(n), kThreads, map, jobs, n, ok_count);
  check_last("merging (looking up)");
}

void merge_apply(const MutableMapView& map, MergeJob* jobs, int32_t n) {
  if (n <= 0) return;
  launch(merge_fill_kernel, static_cast<unsigned>(n), kBlockVoxels, map, jobs);
  launch(merge_publish_kernel, grid_for(n), kThreads, map, jobs, n);
  launch(merge_return_kernel, grid_for(n), kThreads, map, jobs, n);
  check_last("merging");
}

void split_check(const MapView& map, SplitJob* jobs, int32_t n, int32_t* ok_count) {
  if (n <= 0) return;
  launch(split_check_kernel, grid_for(n), kThreads, map, jobs, n, ok_count);
  check_last("splitting (checking)");
}

void split_apply_level(const MutableMapView& map, SplitJob* jobs, int32_t n, float weight_scale) {
  if (n <= 0) return;
  launch(split_sources_kernel, grid_for(n), kThreads, map.read, jobs, n);
  launch(split_fill_kernel, static_cast<unsigned>(n) * kBlockChildren, kBlockVoxels, map, jobs,
         weight_scale);
  launch(split_publish_kernel, grid_for(n), kThreads, map, jobs, n);
  check_last("splitting");
}

void split_finish(const MutableMapView& map, const SplitJob* jobs, int32_t n) {
  if (n <= 0) return;
  launch(split_finish_kernel, grid_for(n), kThreads, map, jobs, n);
  check_last("splitting (returning the parents' blocks)");
}

}  // namespace hivox::cuda

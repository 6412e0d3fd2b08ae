#include "cuda/loop_kernels.h"

#include <cuda_runtime.h>

#include <cfloat>
#include <climits>
#include <iterator>
#include <string>
#include <utility>

#include "core/parallel.h"
#include "cuda/device_helpers.cuh"
#include "cuda/device_memory.h"
#include "hivox/core/device.h"
#include "map/map_kernels.h"
#include "map/sample_kernels.h"

namespace hivox::cuda {

void check_last(const char* what) {
  const cudaError_t e = cudaGetLastError();
  if (e == cudaSuccess) return;
  int device = 0;
  cudaGetDevice(&device);  // the device the loop selected
  cuda_launch_failed(Device::cuda(device),
                     (std::string(what) + ": " + cudaGetErrorString(e)).c_str());
}

namespace {

constexpr int kThreads = 256;

unsigned grid_for(int64_t n, int threads = kThreads) {
  const int64_t blocks = (n + threads - 1) / threads;
  return static_cast<unsigned>(blocks < 1 ? 1 : blocks);
}

/// The current device's multiprocessors (32 where the driver does not say).
int multiprocessors() {
  static const int sms = [] {
    int device = 0, n = 0;
    cudaGetDevice(&device);
    cudaDeviceGetAttribute(&n, cudaDevAttrMultiProcessorCount, device);
    return n > 0 ? n : 32;
  }();
  return sms;
}

/// The allocation walk's visitor: a block's first look-up in the thread stamps it (listed as
/// visible on its first visit this frame) or records it as missing; a block the thread has seen
/// already needs neither again, so its look-up is skipped. It remembers the blocks it looked up
/// in `kSlots` direct-mapped slots: 1 keeps the last one (a thread of one pixel: its band's
/// neighbouring steps cross the same block); a thread of several pixels keeps 16 (neighbouring
/// pixels' bands cross the same blocks).
template <int kSlots>
struct FindVisitor {
  const MapView& map;
  int32_t* stamps;
  int32_t frame;
  const BlockKeySet& missing;
  BlockRef* visible;
  AllocCounters* counters;
  kernels::BlockSlot seen[kSlots];

  __device__ void add_missing(int level, const Vec3i& pos) {
    add_unique(missing, level, pos, &counters->missing);
  }

  __device__ int32_t block(int level, const Vec3i& pos) {
    kernels::BlockSlot& s = seen[kernels::block_slot(level, pos, kSlots)];
    if (s.holds(level, pos)) return s.ptr;
    const LevelView& lv = map.level[level];
    const int32_t entry = find_entry(lv, pos);
    const int32_t ptr = entry == kNoEntry ? kPtrEmpty : lv.entries[entry].ptr;
    if (ptr == kPtrEmpty) add_missing(level, pos);
    const bool first_visit =
        ptr >= 0 && stamps[ptr] != frame && atomicExch(&stamps[ptr], frame) != frame;
    const int32_t slot = append_index(first_visit, &counters->visible);
    if (first_visit) visible[slot] = BlockRef{pos, level, entry, ptr};
    s = {pos, level, ptr};
    return ptr;
  }
};

/// One thread per `kW` x `kH` pixels, each pixel's truncation band walked in turn
/// (kernels::walk_segment); with several pixels the thread remembers 16 blocks across them.
template <int kW, int kH>
__global__ void find_blocks_kernel(MapView map, kernels::DepthFrameView depth, Rigid3f T_wc,
                                   float mu_m, int32_t* stamps, int32_t frame, BlockKeySet missing,
                                   BlockRef* visible, AllocCounters* counters) {
  const int x0 = (blockIdx.x * blockDim.x + threadIdx.x) * kW;
  const int y0 = (blockIdx.y * blockDim.y + threadIdx.y) * kH;
  FindVisitor<kW * kH == 1 ? 1 : 16> visitor{map, stamps, frame, missing, visible, counters};
  for (int dy = 0; dy < kH; ++dy)
    for (int dx = 0; dx < kW; ++dx) {
      const int x = x0 + dx, y = y0 + dy;
      const bool in_image = x < depth.depth_m.width && y < depth.depth_m.height;
      Vec3f a, b;
      const bool valid = in_image && kernels::band_segment(depth, T_wc, mu_m, x, y, &a, &b);
      count_warp(valid, &counters->valid_pixels);
      if (valid) kernels::walk_segment(map, a, b, visitor);
    }
}

/// One CUDA block per missing key: its first thread inserts the block (kernels::allocate_block),
/// then all its threads clear the block's voxels together (coalesced).
__global__ void insert_blocks_kernel(MutableMapView map, BlockKeySet missing, BlockRef* visible,
                                     int32_t* stamps, int32_t frame, AllocCounters* counters,
                                     kernels::SuperBlockBounds* bounds) {
  __shared__ int32_t block;
  if (threadIdx.x == 0) {
    const BlockKey k = missing.list[blockIdx.x];
    int32_t entry = kNoEntry;
    block = kPtrEmpty;
    switch (kernels::allocate_block(map, k.level, k.pos, &entry, &block, false)) {
      case kernels::AllocResult::Allocated:
        stamps[block] = frame;
        visible[atomicAdd(&counters->visible, 1)] = BlockRef{k.pos, k.level, entry, block};
        atomicAdd(&counters->inserted, 1);
        bounds->add_atomic(
            kernels::CoarseOccupancy::super_block_of(k.pos, k.level, map.read.levels));
        break;
      case kernels::AllocResult::HashFull:
        atomicAdd(&counters->hash_full, 1);
        break;
      case kernels::AllocResult::PoolFull:
        atomicAdd(&counters->pool_full, 1);
        break;
    }
  }
  __syncthreads();
  if (block < 0) return;
  TsdfVoxel* v = map.tsdf + static_cast<int64_t>(block) * kBlockVoxels;
  for (int i = threadIdx.x; i < kBlockVoxels; i += blockDim.x) v[i] = TsdfVoxel{};
  if (map.color != nullptr) {
    ColorVoxel* c = map.color + static_cast<int64_t>(block) * kBlockVoxels;
    for (int i = threadIdx.x; i < kBlockVoxels; i += blockDim.x) c[i] = ColorVoxel{};
  }
}

/// One CUDA block per voxel block, one thread per voxel: the per-voxel update of
/// kernels::integrate_block_slices, from the same functions.
template <bool kBilinear>
__global__ void __launch_bounds__(kBlockVoxels)
    integrate_kernel(MutableMapView map, const BlockRef* blocks, const AllocCounters* counters,
                     kernels::DepthFrameView depth, kernels::ColorFrameView color,
                     kernels::IntegrationConstants k) {
  if (static_cast<int32_t>(blockIdx.x) >= counters->visible) return;
  __shared__ SharedSurface summary;
  if (threadIdx.x == 0) summary.clear();
  __syncthreads();
  const BlockRef b = blocks[blockIdx.x];
  const int i = threadIdx.x;  // voxel_index(x, y, z) = x + 8 y + 64 z
  const int x = i & 7, y = (i >> 3) & 7, z = i >> 6;
  const float s = map.read.level[b.level].voxel_size_m;
  const Vec3f origin_c = k.T_cw * (to_float(b.pos) * (static_cast<float>(kBlockSide) * s));
  const Vec3f step_x = k.T_cw.R.col(0) * s, step_y = k.T_cw.R.col(1) * s,
              step_z = k.T_cw.R.col(2) * s;
  const float xf = static_cast<float>(x), yf = static_cast<float>(y), zf = static_cast<float>(z);
  const Vec3f p{origin_c.x + step_y.x * yf + step_z.x * zf + step_x.x * xf,
                origin_c.y + step_y.y * yf + step_z.y * zf + step_x.y * xf,
                origin_c.z + step_y.z * yf + step_z.z * zf + step_x.z * xf};
  int px;
  bool inside;
  float d;
  if constexpr (kBilinear) {
    const Vec2f uv = depth.camera.project(p);
    inside = kernels::nearest_pixel(depth.camera, uv, p.z, &px);
    d = kernels::depth_bilinear(depth.camera, depth.depth_m.data, uv, depth.min_depth_m, k.mu_m);
  } else {
    inside = kernels::project_to_pixel(depth.camera, p, &px);
    d = depth.depth_m.data[px];
  }
  const bool observed =
      inside && d >= depth.min_depth_m && d <= depth.max_depth_m && d - p.z >= -k.mu_m;
  const float eta = d - p.z;
  uint32_t* word =
      reinterpret_cast<uint32_t*>(map.tsdf + static_cast<int64_t>(b.ptr) * kBlockVoxels) + i;
  uint32_t result = *word;
  if (observed) {
    result = kernels::fuse_tsdf_word(result, eta, k.inv_mu, k.max_weight);
    *word = result;
  }
  summary.add(i, static_cast<int>(result >> 16), tsdf_of_word(result));
  if (map.color != nullptr && !color.image.empty() && observed && eta < k.mu_m) {
    ColorVoxel* c = map.color + static_cast<int64_t>(b.ptr) * kBlockVoxels + i;
    if (color.packed != nullptr) {
      uint32_t* cw = reinterpret_cast<uint32_t*>(c);
      *cw = kernels::fuse_color_word(*cw, color.packed[px], k.max_weight);
    } else {
      int cp = px;
      if (color.registered || kernels::project_to_pixel(color.camera, color.T_color_depth * p, &cp))
        kernels::fuse_color(*c, color.image.data[cp], k.max_weight);
    }
  }
  __syncthreads();
  if (threadIdx.x == 0) {
    BlockMeta& meta = map.meta[b.ptr];
    meta.surface = summary.get();
    if (meta.updates < 65535) ++meta.updates;
  }
}

__global__ void pack_color_kernel(const Rgb8* rgb, uint32_t* packed, int64_t n) {
  const int64_t i = static_cast<int64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i < n) packed[i] = kernels::pack_rgb(rgb[i]);
}

__global__ void fill_tiles(kernels::RangeTiles tiles) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= tiles.count()) return;
  tiles.z_min[i] = FLT_MAX;
  tiles.z_max[i] = 0.0f;
}

__global__ void project_blocks_kernel(MapView map, int32_t high_water, Rigid3f T_cw,
                                      PinholeCamera cam, float min_depth_m, float max_depth_m,
                                      kernels::RangeTiles tiles,
                                      kernels::CoarseOccupancy occupancy) {
  const int32_t ptr = blockIdx.x * blockDim.x + threadIdx.x;
  if (ptr >= high_water) return;
  const BlockMeta m = map.meta[ptr];
  if (m.level < 0) return;
  if (occupancy.cells != nullptr) {
    // The bounds cover every block (insertions grow them); a block outside would be a bug, never
    // a write outside the grid.
    const Vec3i c = kernels::CoarseOccupancy::super_block_of(m.pos, m.level, map.levels);
    if (occupancy.covers(c)) occupancy.mark(c);
  }
  kernels::project_block_to_tiles(T_cw, cam, m.pos, map.level[m.level].block_size_m, min_depth_m,
                                  max_depth_m, tiles);
}

/// Pixel (x, y)'s ray: its direction, its tile's depth range and its hints (the frame's depth at
/// the pixel, the warped previous raycast as the fallback).
struct PixelRay {
  Vec3f dir;
  float z_min = 0, z_max = 0;
  kernels::RayHints hints;
};

__device__ PixelRay pixel_ray(const PinholeCamera& cam, const Rigid3f& T_wc,
                              const kernels::RangeTiles& tiles, const kernels::RayMarchConstants& k,
                              const RayHintImages& hint, int x, int y) {
  PixelRay r;
  const int t = tiles.tile_of(x, y);
  r.z_min = tiles.z_min[t];
  r.z_max = tiles.z_max[t];
  const int n = hint.subsample;
  const float start =
      hint.depth_m != nullptr
          ? hint.depth_m[static_cast<int64_t>(n * y + n / 2) * hint.width + n * x + n / 2]
          : 0.0f;
  const float fallback =
      hint.fallback_m != nullptr ? hint.fallback_m[static_cast<int64_t>(y) * cam.width + x] : 0.0f;
  r.hints = kernels::ray_hints(start, fallback, k, r.z_min, r.z_max);
  if (hint.levels != nullptr) r.hints.level = hint.levels[static_cast<int64_t>(y) * cam.width + x];
  r.dir = T_wc.rotate(cam.ray(static_cast<float>(x), static_cast<float>(y)));
  return r;
}

/// One ray's march_from_hint split across the warp's 32 lanes, each lane marching a stretch
/// (kernels::split_march_from_hint); the winning lane writes the ray's pixel and counts its hit,
/// lane `owner` writes a miss. Every lane of the warp calls this with the same ray.
__device__ void split_march_ray(const MapView& map, const Rigid3f& T_wc,
                                const kernels::RayMarchConstants& k,
                                const kernels::RaycastOutputView& out, AllocCounters* counters,
                                const Vec3f& dir, float ray_hint, float z_min, float z_max,
                                int32_t pixel, int owner, kernels::BlockLookupCache& cache) {
  constexpr unsigned kWarp = 0xffffffffu;
  const int lane = static_cast<int>(lane_index());
  kernels::LaneMarch far, front;
  auto march = [&](float from, float to, bool is_front) {
    kernels::LaneMarch& m = is_front ? front : far;
    m = kernels::march_lane(map, cache, T_wc.t, dir, from, to, k, lane, 32);
    return kernels::split_march_result(__ballot_sync(kWarp, m.found),
                                       __ballot_sync(kWarp, m.report.known),
                                       __ballot_sync(kWarp, m.report.started_behind));
  };
  const kernels::SplitChoice c =
      kernels::split_march_from_hint(kernels::hint_stretches(ray_hint, z_min, z_max, k), march);
  if (c.winner < 0) {
    if (lane == owner) kernels::write_ray(out, map, pixel, false, kernels::RayHit{});
  } else if (lane == c.winner) {
    kernels::write_ray(out, map, pixel, true, c.front ? front.hit : far.hit);
    atomicAdd(&counters->raycast_hits, 1);
  }
}

/// With split marches (cast_rays_kernel<true>): where at most `split_at_most` of the warp's rays
/// march (their hint search failed), the warp takes them one after another, each across its
/// lanes (split_march_ray). Returns false, doing nothing, where more rays march: each then
/// marches its own. Every lane of the warp calls this (lanes outside the image march nothing of
/// their own).
__device__ bool split_marches(const MapView& map, const Rigid3f& T_wc,
                              const kernels::RayMarchConstants& k,
                              const kernels::RaycastOutputView& out, AllocCounters* counters,
                              const PixelRay& r, int32_t i, bool marches, int split_at_most,
                              kernels::BlockLookupCache& cache) {
  constexpr unsigned kWarp = 0xffffffffu;
  unsigned pending = __ballot_sync(kWarp, marches);
  if (__popc(pending) > split_at_most) return false;
  while (pending != 0u) {
    const int owner = __ffs(static_cast<int>(pending)) - 1;
    pending &= pending - 1u;
    const Vec3f dir{__shfl_sync(kWarp, r.dir.x, owner), __shfl_sync(kWarp, r.dir.y, owner),
                    __shfl_sync(kWarp, r.dir.z, owner)};
    split_march_ray(map, T_wc, k, out, counters, dir, __shfl_sync(kWarp, r.hints.hint, owner),
                    __shfl_sync(kWarp, r.z_min, owner), __shfl_sync(kWarp, r.z_max, owner),
                    __shfl_sync(kWarp, i, owner), owner, cache);
  }
  return true;
}

/// The ray kernel's threads a block: warps of 8x4 pixels, 4 of them.
constexpr int kRaycastThreadsX = 8, kRaycastThreadsY = 16;
constexpr int kRaycastThreads = kRaycastThreadsX * kRaycastThreadsY;

/// One thread per pixel's ray: the search at its hints, then, where that fails, its march
/// (kernels::cast_ray's two steps; with `kSplit`, split_marches may take the marches). The map is
/// the kernel's __grid_constant__: the functions it calls take the view by reference, which
/// would otherwise copy it onto each thread's stack.
template <bool kSplit>
__device__ HIVOX_FORCEINLINE void cast_ray_of_thread(const MapView& map, PinholeCamera cam,
                                                     Rigid3f T_wc, kernels::RangeTiles tiles,
                                                     kernels::RayMarchConstants k,
                                                     RayHintImages hint,
                                                     kernels::RaycastOutputView out,
                                                     AllocCounters* counters, int split_at_most) {
  const int x = blockIdx.x * blockDim.x + threadIdx.x;
  const int y = blockIdx.y * blockDim.y + threadIdx.y;
  const bool in_image = x < cam.width && y < cam.height;
  const int32_t i = in_image ? y * cam.width + x : -1;
  PixelRay r;
  kernels::BlockLookupCache cache;
  kernels::RayHit hit;
  kernels::RayOutcome outcome = kernels::RayOutcome::Miss;
  if (in_image) {
    r = pixel_ray(cam, T_wc, tiles, k, hint, x, y);
    outcome = kernels::search_at_hints(map, cache, T_wc.t, r.dir, r.hints, r.z_max, k, &hit);
  }
  bool found = outcome != kernels::RayOutcome::Miss;
  const bool marches = in_image && !found && r.z_max > 0.0f;
  if constexpr (kSplit) {
    if (split_marches(map, T_wc, k, out, counters, r, i, marches, split_at_most, cache)) {
      // The marches are written; the rest of the warp's rays now.
      if (in_image && !marches) kernels::write_ray(out, map, i, found, hit);
      count_warp(found, &counters->raycast_hits);
      return;
    }
  }
  if (marches)
    found = kernels::march_from_hint(map, cache, T_wc.t, r.dir, r.hints.hint, r.z_min, r.z_max, k,
                                     &hit);
  if (in_image) kernels::write_ray(out, map, i, found, hit);
  count_warp(found, &counters->raycast_hits);
}

/// Held to 3 blocks (12 warps) a multiprocessor, as it ran before the search behind a sliver of
/// unobserved voxels (kernels::search_back_for_crossing) took it from 162 to ~196 registers a
/// thread (10 warps): ptxas fits 168 with 28 bytes of spill stores (sm_90, CUDA 13).
template <bool kSplit>
__global__ void __launch_bounds__(kRaycastThreads, 3)
    cast_rays_kernel(const __grid_constant__ MapView map, PinholeCamera cam, Rigid3f T_wc,
                     kernels::RangeTiles tiles, kernels::RayMarchConstants k, RayHintImages hint,
                     kernels::RaycastOutputView out, AllocCounters* counters, int split_at_most) {
  cast_ray_of_thread<kSplit>(map, cam, T_wc, tiles, k, hint, out, counters, split_at_most);
}

/// cast_rays_kernel with at most `kRegisters` registers a thread: the launch bounds ask for as
/// many blocks at once as 65 536 registers a multiprocessor (sm_70 on) hold; the rest spills.
template <bool kSplit, int kRegisters>
__global__ void __launch_bounds__(kRaycastThreads, 65536 / (kRaycastThreads * kRegisters))
    capped_cast_rays_kernel(const __grid_constant__ MapView map, PinholeCamera cam, Rigid3f T_wc,
                            kernels::RangeTiles tiles, kernels::RayMarchConstants k,
                            RayHintImages hint, kernels::RaycastOutputView out,
                            AllocCounters* counters, int split_at_most) {
  cast_ray_of_thread<kSplit>(map, cam, T_wc, tiles, k, hint, out, counters, split_at_most);
}

/// The first of the raycast's two kernels (RaycastLaunch::march_queue): each pixel's ray searched
/// at its hints; a ray whose search fails and that has a range to march goes into `queue`
/// (queue[0] counts them, queue[1] is march_queued_rays_kernel's, the pixels follow) for
/// march_queued_rays_kernel; the others are written. Without the march's code, its threads take
/// fewer registers than cast_rays_kernel's.
__global__ void __launch_bounds__(kRaycastThreads)
    search_rays_kernel(const __grid_constant__ MapView map, PinholeCamera cam, Rigid3f T_wc,
                       kernels::RangeTiles tiles, kernels::RayMarchConstants k, RayHintImages hint,
                       kernels::RaycastOutputView out, AllocCounters* counters, int32_t* queue) {
  const int x = blockIdx.x * blockDim.x + threadIdx.x;
  const int y = blockIdx.y * blockDim.y + threadIdx.y;
  const bool in_image = x < cam.width && y < cam.height;
  bool found = false;
  if (in_image) {
    const int32_t i = y * cam.width + x;
    const PixelRay r = pixel_ray(cam, T_wc, tiles, k, hint, x, y);
    kernels::BlockLookupCache cache;
    kernels::RayHit hit;
    found = kernels::search_at_hints(map, cache, T_wc.t, r.dir, r.hints, r.z_max, k, &hit) !=
            kernels::RayOutcome::Miss;
    if (!found && r.z_max > 0.0f)
      queue[2 + atomicAdd(queue, 1)] = i;
    else
      kernels::write_ray(out, map, i, found, hit);
  }
  count_warp(found, &counters->raycast_hits);
}

/// The second of the raycast's two kernels: each warp takes the next queued ray (of queue[0],
/// queue[1] counting those taken) until none is left, each across its 32 lanes
/// (split_march_ray): a warp with a long march takes fewer. The same ray as
/// search_rays_kernel's (pixel_ray).
__global__ void __launch_bounds__(kRaycastThreads)
    march_queued_rays_kernel(const __grid_constant__ MapView map, PinholeCamera cam, Rigid3f T_wc,
                             kernels::RangeTiles tiles, kernels::RayMarchConstants k,
                             RayHintImages hint, kernels::RaycastOutputView out,
                             AllocCounters* counters, int32_t* queue) {
  constexpr unsigned kWarp = 0xffffffffu;
  const int32_t n = queue[0];
  kernels::BlockLookupCache cache;
  for (;;) {
    int32_t q = 0;
    if (lane_index() == 0) q = atomicAdd(&queue[1], 1);
    q = __shfl_sync(kWarp, q, 0);
    if (q >= n) break;
    const int32_t i = queue[2 + q];
    const PixelRay r = pixel_ray(cam, T_wc, tiles, k, hint, i % cam.width, i / cam.width);
    split_march_ray(map, T_wc, k, out, counters, r.dir, r.hints.hint, r.z_min, r.z_max, i, 0,
                    cache);
  }
}

__global__ void warp_clear_kernel(uint32_t* nearest, int64_t n) {
  const int64_t i = static_cast<int64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i < n) nearest[i] = __float_as_uint(FLT_MAX);
}

/// Each hit of the previous raycast onto its pixel of the new view: the nearest wins (positive
/// floats order as their bits do).
__global__ void warp_land_kernel(kernels::WarpView view, const float* depth, const Vec3f* points,
                                 const Vec3f* normals, int64_t n, uint32_t* nearest) {
  const int64_t i = static_cast<int64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= n) return;
  float u, v;
  const float z = kernels::warp_landing(view, depth[i], points[i], normals[i], &u, &v);
  if (z > 0.0f)
    atomicMin(&nearest[static_cast<int64_t>(v) * view.width + static_cast<int>(u)],
              __float_as_uint(z));
}

__global__ void warp_resolve_kernel(kernels::WarpView view, const uint32_t* nearest, float* out) {
  const int x = blockIdx.x * blockDim.x + threadIdx.x;
  const int y = blockIdx.y * blockDim.y + threadIdx.y;
  if (x >= view.width || y >= view.height) return;
  auto landed = [&](int u, int v) {
    return u >= 0 && v >= 0 && u < view.width && v < view.height
               ? __uint_as_float(nearest[static_cast<int64_t>(v) * view.width + u])
               : FLT_MAX;
  };
  float front = FLT_MAX;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) front = fminf(front, landed(x + dx, y + dy));
  float z = landed(x, y);
  if (!(z < FLT_MAX)) z = kernels::warp_hole(landed, x, y, view.max_gap_m);
  out[static_cast<int64_t>(y) * view.width + x] = kernels::warp_keep(z, front, view.max_gap_m);
}

__global__ void filter_depth_kernel(ImageView<const float> in, float* out, int radius, float inv_px,
                                    float inv_d, float min_m, float max_m) {
  const int x = blockIdx.x * blockDim.x + threadIdx.x;
  const int y = blockIdx.y * blockDim.y + threadIdx.y;
  if (x >= in.width || y >= in.height) return;
  const int64_t i = static_cast<int64_t>(y) * in.width + x;
  if (radius > 0) {
    out[i] = kernels::bilateral_depth(in, x, y, radius, inv_px, inv_d, min_m, max_m);
  } else {
    const float d = in(x, y);
    out[i] = d >= min_m && d <= max_m ? d : 0.0f;
  }
}

__global__ void downsample_depth_kernel(const float* in, float* out, int w, int h,
                                        float max_jump_ratio) {
  const int x = blockIdx.x * blockDim.x + threadIdx.x;
  const int y = blockIdx.y * blockDim.y + threadIdx.y;
  if (x >= w || y >= h) return;
  const int in_w = 2 * w;
  float d[4];
  for (int k = 0; k < 4; ++k) d[k] = in[(2 * y + (k >> 1)) * in_w + 2 * x + (k & 1)];
  const int mask = kernels::same_surface_2x2(d, max_jump_ratio);
  float sum = 0.0f;
  for (int k = 0; k < 4; ++k)
    if (mask & (1 << k)) sum += d[k];
  out[y * w + x] = mask != 0 ? sum / static_cast<float>(__popc(mask)) : 0.0f;
}

__global__ void unproject_kernel(const float* depth, PinholeCamera cam, Vec3f* points) {
  const int x = blockIdx.x * blockDim.x + threadIdx.x;
  const int y = blockIdx.y * blockDim.y + threadIdx.y;
  if (x >= cam.width || y >= cam.height) return;
  const int64_t i = static_cast<int64_t>(y) * cam.width + x;
  const float d = depth[i];
  points[i] =
      d > 0.0f ? cam.unproject(static_cast<float>(x), static_cast<float>(y), d) : Vec3f{0, 0, 0};
}

__global__ void normals_kernel(ImageView<const Vec3f> points, float max_jump_ratio, Vec3f* normals,
                               int32_t* valid) {
  const int x = blockIdx.x * blockDim.x + threadIdx.x;
  const int y = blockIdx.y * blockDim.y + threadIdx.y;
  const bool in_image = x < points.width && y < points.height;
  bool has_normal = false;
  if (in_image) {
    const Vec3f n = kernels::normal_from_points(points, x, y, max_jump_ratio);
    normals[static_cast<int64_t>(y) * points.width + x] = n;
    has_normal = !kernels::is_zero(n);
  }
  if (valid != nullptr) count_warp(has_normal, valid);
}

__global__ void downsample_model_kernel(const Vec3f* points, const Vec3f* normals,
                                        const float* depth, int in_w, Vec3f* out_points,
                                        Vec3f* out_normals, float* out_depth, int w, int h,
                                        float max_jump_ratio) {
  const int x = blockIdx.x * blockDim.x + threadIdx.x;
  const int y = blockIdx.y * blockDim.y + threadIdx.y;
  if (x >= w || y >= h) return;
  float dk[4];
  int64_t src[4];
  for (int k = 0; k < 4; ++k) {
    src[k] = static_cast<int64_t>(2 * y + (k >> 1)) * in_w + 2 * x + (k & 1);
    dk[k] = kernels::is_zero(normals[src[k]]) ? 0.0f : depth[src[k]];
  }
  const int mask = kernels::same_surface_2x2(dk, max_jump_ratio);
  Vec3f p{0, 0, 0}, n{0, 0, 0};
  float d = 0.0f;
  for (int k = 0; k < 4; ++k) {
    if (!(mask & (1 << k))) continue;
    p += points[src[k]];
    n += normals[src[k]];
    d += dk[k];
  }
  const int count = __popc(mask);
  const int64_t o = static_cast<int64_t>(y) * w + x;
  out_points[o] = count > 0 ? p / static_cast<float>(count) : Vec3f{0, 0, 0};
  out_normals[o] = count > 0 ? normalized(n) : Vec3f{0, 0, 0};
  out_depth[o] = count > 0 ? d / static_cast<float>(count) : 0.0f;
}

// The sums in the layout of track/gauss_newton.h: A upper (21), b (6), r2, distance, inliers.
constexpr int kSums = kernels::kIcpSums;

/// A step of the warp's reduce-scatter of `v` (32 slots, the first 2 `kHalf` live): lanes
/// `kHalf` apart swap halves, each keeping the half its bit `kHalf` picks, plus the partner's copy.
template <int kHalf>
__device__ HIVOX_FORCEINLINE void reduce_scatter_step(float (&v)[32], int lane) {
  const bool upper = (lane & kHalf) != 0;
#pragma unroll
  for (int j = 0; j < kHalf; ++j) {
    const float lo = v[j], hi = v[j + kHalf];
    v[j] = (upper ? hi : lo) + __shfl_xor_sync(0xFFFFFFFFu, upper ? lo : hi, kHalf);
  }
}

/// One ICP pass: each block sums its pixels' terms at pose `c.T_wc`, the last block to finish
/// sums the blocks in doubles into `sums`.
__device__ HIVOX_FORCEINLINE void icp_pass(const kernels::IcpPass& c, const Vec3f* points_c,
                                           const Vec3f* normals_c, int64_t pixels,
                                           const Vec3f* model_points, const Vec3f* model_normals,
                                           float* partials, unsigned* done, double* sums) {
  // Each thread sums the terms of its pixels (a grid-stride loop: a few pixels a thread), in 32
  // slots (the sums and zeros) for the warp's reduce-scatter below.
  static_assert(kSums <= 32, "one sum a lane in the warp's reduce-scatter");
  float v[32];
#pragma unroll
  for (int k = 0; k < 32; ++k) v[k] = 0.0f;
  const int64_t stride = static_cast<int64_t>(gridDim.x) * blockDim.x;
  for (int64_t i = static_cast<int64_t>(blockIdx.x) * blockDim.x + threadIdx.x; i < pixels;
       i += stride) {
    const Vec3f p_c = points_c[i], n_c = normals_c[i];
    const Vec3f p_w = c.T_wc * p_c;
    int32_t m = 0;
    const bool inside = kernels::icp_model_pixel(c, p_w, &m);
    const kernels::IcpTerm t =
        kernels::icp_pair_term(c, p_c, n_c, p_w, inside, model_points[m], model_normals[m]);
    if (t.paired) {
      const float sw = t.sqrt_weight;
      const float J[6] = {sw * t.J.t.x, sw * t.J.t.y, sw * t.J.t.z,
                          sw * t.J.w.x, sw * t.J.w.y, sw * t.J.w.z};
      const float r = sw * t.r;
      int k = 0;
      for (int a = 0; a < 6; ++a)
        for (int b = a; b < 6; ++b) v[k++] += J[a] * J[b];
      for (int a = 0; a < 6; ++a) v[kernels::kIcpB + a] += J[a] * r;
      v[kernels::kIcpR2] += t.r * t.r;
      v[kernels::kIcpDistance] += t.distance_m;
      v[kernels::kIcpInliers] += 1.0f;
    }
  }
  // The block's sums: within each warp by a reduce-scatter (16 + 8 + 4 + 2 + 1 = 31 shuffles,
  // against 150 for a tree per sum), which leaves lane l with the warp's sum l; then across the
  // warps.
  __shared__ float warp_sums[kThreads / 32][kSums];
  const int lane = threadIdx.x & 31, warp = threadIdx.x >> 5;
  reduce_scatter_step<16>(v, lane);
  reduce_scatter_step<8>(v, lane);
  reduce_scatter_step<4>(v, lane);
  reduce_scatter_step<2>(v, lane);
  reduce_scatter_step<1>(v, lane);
  if (lane < kSums) warp_sums[warp][lane] = v[0];
  __syncthreads();
  if (threadIdx.x < kSums) {
    float x = 0.0f;
    for (int w = 0; w < kThreads / 32; ++w) x += warp_sums[w][threadIdx.x];
    partials[static_cast<int64_t>(blockIdx.x) * kSums + threadIdx.x] = x;
    __threadfence();
  }
  // The last block to finish sums the blocks' sums in doubles, one warp per sum at a time: lane
  // l takes blocks l, l + 32, ..., then the lanes are summed by a fixed tree (the same system
  // whatever the timing).
  __shared__ bool last;
  __syncthreads();
  if (threadIdx.x == 0) last = atomicAdd(done, 1u) == gridDim.x - 1;
  __syncthreads();
  if (!last) return;
  for (int k = warp; k < kSums; k += kThreads / 32) {
    double s = 0.0;
    for (unsigned b = lane; b < gridDim.x; b += 32)
      s += __ldcg(&partials[static_cast<int64_t>(b) * kSums + k]);
    for (int o = 16; o > 0; o >>= 1) s += __shfl_down_sync(0xFFFFFFFFu, s, o);
    if (lane == 0) sums[k] = s;
  }
  if (threadIdx.x == 0) *done = 0;  // ready for the next pass
}

__global__ void __launch_bounds__(kThreads)
    icp_kernel(const kernels::IcpPass c, const Vec3f* points_c, const Vec3f* normals_c,
               int64_t pixels, const Vec3f* model_points, const Vec3f* model_normals,
               float* partials, unsigned* done, double* sums) {
  icp_pass(c, points_c, normals_c, pixels, model_points, model_normals, partials, done, sums);
}

/// The pass with Gauss-Newton on the device: the pose comes from `state`, and a level the state
/// skips gets no pass. Held to 64 registers (4 blocks an SM, as the host's pass runs): the pose in
/// registers would take it to 79. With `kModelPoseInMemory`, the model's pose comes from
/// `T_model_cw` (the arguments are then every frame's, for a LaunchGraph), else from `c`
/// (T_model_cw not read): the model's pose copied into the pass takes 52 more bytes of spills a
/// thread.
template <bool kModelPoseInMemory>
__global__ void __launch_bounds__(kThreads, 4)
    icp_state_kernel(kernels::IcpPass c, const Vec3f* points_c, const Vec3f* normals_c,
                     int64_t pixels, const Vec3f* model_points, const Vec3f* model_normals,
                     float* partials, unsigned* done, double* sums, const kernels::IcpState* state,
                     const Rigid3f* T_model_cw, int level) {
  if (kernels::icp_skips(*state, level)) return;  // the same for every thread: no pass
  c.T_wc = kernels::rigid3f_of(state->T);
  if constexpr (kModelPoseInMemory) c.T_model_cw = *T_model_cw;
  icp_pass(c, points_c, normals_c, pixels, model_points, model_normals, partials, done, sums);
}

/// Gauss-Newton's step after a pass at `level` (none where the pass did nothing). A kernel of its
/// own: inside the pass's last block, the 6x6 solve would raise the pass's registers (62 to 89)
/// and halve its occupancy.
__global__ void icp_step_kernel(kernels::IcpState* state, const double* sums, int level,
                                double convergence_step) {
  if (!kernels::icp_skips(*state, level))
    kernels::icp_update(*state, sums, level, convergence_step);
}

dim3 image_grid(int w, int h, dim3 threads) {
  return dim3((w + threads.x - 1) / threads.x, (h + threads.y - 1) / threads.y);
}

}  // namespace

void find_blocks(const MapView& map, const kernels::DepthFrameView& depth, const Rigid3f& T_wc,
                 float mu_m, int32_t* stamps, int32_t frame, const BlockKeySet& missing,
                 BlockRef* visible, AllocCounters* counters, int pixels_per_thread) {
  const dim3 threads(16, 8);
  const int w = depth.depth_m.width, h = depth.depth_m.height;
  switch (pixels_per_thread) {  // the caller checked it (1, 2 or 4)
    case 2:
      launch(find_blocks_kernel<2, 1>, image_grid((w + 1) / 2, h, threads), threads, map, depth,
             T_wc, mu_m, stamps, frame, missing, visible, counters);
      break;
    case 4:
      launch(find_blocks_kernel<2, 2>, image_grid((w + 1) / 2, (h + 1) / 2, threads), threads, map,
             depth, T_wc, mu_m, stamps, frame, missing, visible, counters);
      break;
    default:
      launch(find_blocks_kernel<1, 1>, image_grid(w, h, threads), threads, map, depth, T_wc, mu_m,
             stamps, frame, missing, visible, counters);
  }
  check_last("allocation (finding blocks)");
}

void insert_blocks(const MutableMapView& map, const BlockKeySet& missing, int32_t count,
                   BlockRef* visible, int32_t* stamps, int32_t frame, AllocCounters* counters,
                   kernels::SuperBlockBounds* bounds) {
  if (count <= 0) return;
  launch(insert_blocks_kernel, static_cast<unsigned>(count), 128, map, missing, visible, stamps,
         frame, counters, bounds);
  check_last("allocation (inserting blocks)");
}

void integrate(const MutableMapView& map, const BlockRef* blocks, int32_t max_blocks,
               const AllocCounters* counters, const kernels::DepthFrameView& depth,
               const kernels::ColorFrameView& color, const kernels::IntegrationConstants& k) {
  if (max_blocks <= 0) return;
  if (k.bilinear_depth)
    launch(integrate_kernel<true>, max_blocks, kBlockVoxels, map, blocks, counters, depth, color,
           k);
  else
    launch(integrate_kernel<false>, max_blocks, kBlockVoxels, map, blocks, counters, depth, color,
           k);
  check_last("integration");
}

void pack_color(const Rgb8* rgb, uint32_t* packed, int64_t n) {
  if (n <= 0) return;
  launch(pack_color_kernel, grid_for(n), kThreads, rgb, packed, n);
  check_last("packing colour");
}

namespace {

/// The ray kernels' type (cast_rays_kernel and capped_cast_rays_kernel alike).
using RayKernel = void (*)(MapView, PinholeCamera, Rigid3f, kernels::RangeTiles,
                           kernels::RayMarchConstants, RayHintImages, kernels::RaycastOutputView,
                           AllocCounters*, int);

/// The ray kernel with the cap of kRaycastRegisterCaps that `registers` names, else (0;
/// GpuReconstruction lets no other count through) the one without.
template <bool kSplit, std::size_t... kCap>
RayKernel ray_kernel(int registers, std::index_sequence<kCap...>) {
  const RayKernel capped[] = {capped_cast_rays_kernel<kSplit, kRaycastRegisterCaps[kCap]>...};
  for (std::size_t i = 0; i < sizeof...(kCap); ++i)
    if (registers == kRaycastRegisterCaps[i]) return capped[i];
  return cast_rays_kernel<kSplit>;
}

RayKernel ray_kernel(const RaycastLaunch& how) {
  const auto caps = std::make_index_sequence<std::size(kRaycastRegisterCaps)>();
  return how.split_at_most > 0 ? ray_kernel<true>(how.registers_at_most, caps)
                               : ray_kernel<false>(how.registers_at_most, caps);
}

}  // namespace

int raycast_kernel_registers(const RaycastLaunch& how) {
#if defined(HIVOX_CUDA_EMULATION)
  static_cast<void>(how);
  return 0;
#else
  cudaFuncAttributes attributes{};
  check_status(cudaFuncGetAttributes(&attributes, ray_kernel(how)),
               "asking for the raycast kernel's registers");
  return attributes.numRegs;
#endif
}

void raycast(const MapView& map, int32_t high_water, const PinholeCamera& camera,
             const Rigid3f& T_wc, float min_depth_m, float max_depth_m, kernels::RangeTiles tiles,
             const kernels::RayMarchConstants& k, const RayHintImages& hint,
             const kernels::RaycastOutputView& out, AllocCounters* counters,
             const RaycastLaunch& how) {
  min_depth_m = kernels::nearest_ray_start(min_depth_m);  // as the CPU's raycaster
  launch(fill_tiles, grid_for(tiles.count()), kThreads, tiles);
  if (k.occupancy.cells != nullptr)
    check_status(
        cudaMemsetAsync(k.occupancy.cells, 0,
                        static_cast<std::size_t>(k.occupancy.cell_count()) * sizeof(int32_t)),
        "clearing the coarse occupancy grid");
  if (high_water > 0)
    launch(project_blocks_kernel, grid_for(high_water), kThreads, map, high_water, T_wc.inverse(),
           camera, min_depth_m, max_depth_m, tiles, k.occupancy);
  // Warps of 8x4 pixels: their rays stay closer together than those of 16x2, so they
  // diverge less (1 % faster than 16x2 on the H200).
  const dim3 threads(kRaycastThreadsX, kRaycastThreadsY);
  const dim3 grid = image_grid(camera.width, camera.height, threads);
  if (how.march_queue != nullptr &&
      static_cast<int64_t>(camera.width) * camera.height <= how.march_queue_pixels) {
    check_status(cudaMemsetAsync(how.march_queue, 0, 2 * sizeof(int32_t)),
                 "clearing the raycast's queue");
    launch(search_rays_kernel, grid, threads, map, camera, T_wc, tiles, k, hint, out, counters,
           how.march_queue);
    // Warps enough for every multiprocessor to hold as many as fit; each takes a ray at a time.
    launch(march_queued_rays_kernel, 4u * static_cast<unsigned>(multiprocessors()), kRaycastThreads,
           map, camera, T_wc, tiles, k, hint, out, counters, how.march_queue);
  } else {
    launch(ray_kernel(how), grid, threads, map, camera, T_wc, tiles, k, hint, out, counters,
           how.split_at_most);
  }
  check_last("raycast");
}

void warp_depth(const kernels::WarpView& view, const float* depth, const Vec3f* points,
                const Vec3f* normals, int64_t from_pixels, uint32_t* nearest, float* out) {
  const int64_t n = static_cast<int64_t>(view.width) * view.height;
  launch(warp_clear_kernel, grid_for(n), kThreads, nearest, n);
  if (from_pixels > 0)
    launch(warp_land_kernel, grid_for(from_pixels), kThreads, view, depth, points, normals,
           from_pixels, nearest);
  const dim3 threads(32, 8);
  launch(warp_resolve_kernel, image_grid(view.width, view.height, threads), threads, view, nearest,
         out);
  check_last("warping the previous raycast");
}

void filter_depth(const float* in, float* out, int width, int height, int radius,
                  float inv_2sigma_px2, float inv_2sigma_d2, float min_m, float max_m) {
  const dim3 threads(32, 8);
  launch(filter_depth_kernel, image_grid(width, height, threads), threads,
         ImageView<const float>{in, width, height}, out, radius, inv_2sigma_px2, inv_2sigma_d2,
         min_m, max_m);
  check_last("depth filter");
}

void downsample_depth(const float* in, float* out, int out_width, int out_height,
                      float max_jump_ratio) {
  const dim3 threads(32, 8);
  launch(downsample_depth_kernel, image_grid(out_width, out_height, threads), threads, in, out,
         out_width, out_height, max_jump_ratio);
  check_last("depth downsampling");
}

void points_and_normals(const float* depth, const PinholeCamera& camera, float max_jump_ratio,
                        Vec3f* points, Vec3f* normals, int32_t* valid) {
  const dim3 threads(32, 8);
  const dim3 grid = image_grid(camera.width, camera.height, threads);
  launch(unproject_kernel, grid, threads, depth, camera, points);
  launch(normals_kernel, grid, threads, ImageView<const Vec3f>{points, camera.width, camera.height},
         max_jump_ratio, normals, valid);
  check_last("points and normals");
}

void downsample_model(const Vec3f* points, const Vec3f* normals, const float* depth, int in_width,
                      Vec3f* out_points, Vec3f* out_normals, float* out_depth, int out_width,
                      int out_height, float max_jump_ratio) {
  const dim3 threads(32, 8);
  launch(downsample_model_kernel, image_grid(out_width, out_height, threads), threads, points,
         normals, depth, in_width, out_points, out_normals, out_depth, out_width, out_height,
         max_jump_ratio);
  check_last("model downsampling");
}

namespace {
/// Blocks of an ICP pass: enough to fill the device a few times over, so that the last block's
/// sum over their partial sums stays short.
unsigned icp_blocks(int64_t pixels) {
  const unsigned needed = grid_for(pixels);
  const unsigned most = 4u * static_cast<unsigned>(multiprocessors());
  return needed < most ? needed : most;
}
}  // namespace

int64_t icp_partials_size(int64_t pixels) {
  return static_cast<int64_t>(grid_for(pixels)) * kSums;
}

void icp_reduce(const kernels::IcpPass& pass, const Vec3f* points_c, const Vec3f* normals_c,
                int64_t pixels, const Vec3f* model_points, const Vec3f* model_normals,
                float* partials, unsigned* done, double* sums, double* host_sums) {
  const unsigned blocks = icp_blocks(pixels);
  launch(icp_kernel, blocks, kThreads, pass, points_c, normals_c, pixels, model_points,
         model_normals, partials, done, sums);
  check_last("ICP reduction");
  copy_to_host(host_sums, sums, kSums * sizeof(double), "ICP reduction (copying the sums)");
}

void icp_pass_on_device(const kernels::IcpPass& pass, const Vec3f* points_c, const Vec3f* normals_c,
                        int64_t pixels, const Vec3f* model_points, const Vec3f* model_normals,
                        float* partials, unsigned* done, double* sums, kernels::IcpState* state,
                        const Rigid3f* T_model_cw, int level, double convergence_step) {
  const unsigned blocks = icp_blocks(pixels);
  if (T_model_cw != nullptr)
    launch(icp_state_kernel<true>, blocks, kThreads, pass, points_c, normals_c, pixels,
           model_points, model_normals, partials, done, sums, state, T_model_cw, level);
  else
    launch(icp_state_kernel<false>, blocks, kThreads, pass, points_c, normals_c, pixels,
           model_points, model_normals, partials, done, sums, state, T_model_cw, level);
  launch(icp_step_kernel, 1, 1, state, sums, level, convergence_step);
  check_last("ICP pass");
}

LaunchesOn::LaunchesOn(void* stream) : previous_(hivox::detail::launch_stream()) {
  hivox::detail::launch_stream() = static_cast<cudaStream_t>(stream);
}
LaunchesOn::~LaunchesOn() {
  hivox::detail::launch_stream() = static_cast<cudaStream_t>(previous_);
}

LaunchGraph::~LaunchGraph() {
  if (exec_ != nullptr) cudaGraphExecDestroy(static_cast<cudaGraphExec_t>(exec_));
  if (graph_ != nullptr) cudaGraphDestroy(static_cast<cudaGraph_t>(graph_));
  if (stream_ != nullptr) cudaStreamDestroy(static_cast<cudaStream_t>(stream_));
}

void LaunchGraph::run(const std::function<void()>& record, const char* what) {
  if (!launched_) {
    record();
    launched_ = true;
    return;
  }
  if (exec_ == nullptr) {
    cudaStream_t stream = nullptr;
    check_status(cudaStreamCreateWithFlags(&stream, cudaStreamNonBlocking), what);
    stream_ = stream;
    check_status(cudaStreamBeginCapture(stream, cudaStreamCaptureModeThreadLocal), what);
    cudaStream_t& launches = hivox::detail::launch_stream();
    cudaGraph_t graph = nullptr;
    launches = stream;
    try {
      record();
    } catch (...) {
      launches = nullptr;
      cudaStreamEndCapture(stream, &graph);
      if (graph != nullptr) cudaGraphDestroy(graph);
      throw;
    }
    launches = nullptr;
    check_status(cudaStreamEndCapture(stream, &graph), what);
    graph_ = graph;
    cudaGraphExec_t exec = nullptr;
    check_status(cudaGraphInstantiate(&exec, graph, 0), what);
    exec_ = exec;
  }
  check_status(cudaGraphLaunch(static_cast<cudaGraphExec_t>(exec_), nullptr), what);
}

}  // namespace hivox::cuda

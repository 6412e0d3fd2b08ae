#include "hivox/cuda/gpu_reconstruction.h"

#include <cuda_runtime_api.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <limits>
#include <optional>
#include <utility>

#include "core/parallel.h"
#include "cuda/device_memory.h"
#include "cuda/loop_kernels.h"
#include "fusion/integration_frame.h"
#include "hivox/core/error.h"
#include "hivox/core/log.h"
#include "hivox/core/timer.h"
#include "hivox/map/hierarchy_edit.h"
#include "map/hierarchy_kernels.h"
#include "map/map_access.h"
#include "track/icp_solver.h"

namespace hivox::cuda {

namespace {

/// memcpy across the CPU's threads in 256 KB chunks: one thread copying a frame into pinned
/// memory takes longer than the transfer that follows.
void parallel_copy(void* dst, const void* src, std::size_t bytes) {
  constexpr std::size_t kChunk = std::size_t{256} << 10;
  const auto chunks = static_cast<int64_t>((bytes + kChunk - 1) / kChunk);
  parallel_for(chunks, [&](int64_t c) {
    const std::size_t begin = static_cast<std::size_t>(c) * kChunk;
    std::memcpy(static_cast<char*>(dst) + begin, static_cast<const char*>(src) + begin,
                std::min(kChunk, bytes - begin));
  });
}

void wait_for_device(const char* stage) {
  check_status(cudaDeviceSynchronize(), stage);
}

/// The counters of a device map, laid out as one array (see MutableMapView's pointers).
constexpr int kExcessCount = 0;              // kMaxLevels: free excess entries per level
constexpr int kBlockFreeCount = kMaxLevels;  // free pool blocks
constexpr int kLevelCount = kMaxLevels + 1;  // kMaxLevels: blocks per level
constexpr int kHighWater = 2 * kMaxLevels + 1;
constexpr int kCounters = 2 * kMaxLevels + 2;
/// Refinement's candidate lists come back with their counts up to this many entries (a few
/// hundred are usual); the rest in a second copy.
constexpr std::size_t kRefineListHead = 1024;
/// Refinement's counts on the device: [0, 3) RefineLists::counts, then the merges and the
/// splits whose check passed (refine_at_once).
constexpr int kMergesOk = 3, kSplitsOk = 4, kRefineCounts = 5;

/// Stack bytes a GPU thread gets (see Impl's constructor).
constexpr std::size_t kStackBytes = 4096;

struct ImageLevel {
  PinholeCamera camera;
  Buffer<float> depth;
  Buffer<Vec3f> points, normals;
};

/// Device buffer `b` holding at least `n` elements (grown by half again when short); `*total`
/// (when not null) counts its bytes.
template <typename T>
void grow(Buffer<T>& b, std::size_t n, int64_t* total) {
  if (b.size() >= n) return;
  if (total != nullptr) *total -= static_cast<int64_t>(b.size() * sizeof(T));  // the old one goes
  b.reset(n + n / 2, total);
}

/// `on_device()`; where the device has no memory left for it (its map filled it), the same made
/// by `on_host()` from the map taken to the host, with a warning naming `what`.
template <typename OnDevice, typename OnHost>
auto on_device_else_host(const char* what, OnDevice&& on_device, OnHost&& on_host) {
  try {
    return on_device();
  } catch (const Error& e) {
    if (e.code() != ErrorCode::OutOfCapacity) throw;
    log::warn("{}: {}; made on the host instead", what, e.what());
    return on_host();
  }
}

/// A raycast's images in device memory (`camera`'s pixels each), copied to the host.
RaycastResult download_raycast(const PinholeCamera& camera, const Pose& T_wc, bool has_color,
                               const kernels::RaycastOutputView& images) {
  RaycastResult r;
  r.camera = camera;
  r.T_wc = T_wc;
  const int w = camera.width, h = camera.height;
  const auto n = static_cast<std::size_t>(w) * h;
  r.depth_m.resize(w, h);
  r.points_w.resize(w, h);
  r.normals_w.resize(w, h);
  r.colors.resize(w, h);
  r.levels.resize(w, h);
  copy_to_host(r.depth_m.data(), images.depth_m, n * sizeof(float), "raycast (depth)");
  copy_to_host(r.points_w.data(), images.points_w, n * sizeof(Vec3f), "raycast (points)");
  copy_to_host(r.normals_w.data(), images.normals_w, n * sizeof(Vec3f), "raycast (normals)");
  copy_to_host(r.colors.data(), images.colors, n * sizeof(Rgb8), "raycast (colours)");
  copy_to_host(r.levels.data(), images.levels, n * sizeof(int8_t), "raycast (levels)");
  r.has_color = has_color;
  return r;
}

/// The images of a raycast made for the host (a render), freed with it.
struct RaycastImages {
  Buffer<float> depth;
  Buffer<Vec3f> points, normals;
  Buffer<Rgb8> colors;
  Buffer<int8_t> levels;

  explicit RaycastImages(std::size_t pixels) {
    depth.reset(pixels, nullptr);
    points.reset(pixels, nullptr);
    normals.reset(pixels, nullptr);
    colors.reset(pixels, nullptr);
    levels.reset(pixels, nullptr);
  }
  kernels::RaycastOutputView view() const {
    return {depth.get(), points.get(), normals.get(), colors.get(), levels.get()};
  }
};

}  // namespace

namespace {
/// CUDA device `index`'s properties; nullopt when there is no such device (no driver, no GPU).
std::optional<cudaDeviceProp> properties_of(int index) {
  int count = 0;
  cudaDeviceProp prop;
  if (cudaGetDeviceCount(&count) != cudaSuccess || index < 0 || index >= count ||
      cudaGetDeviceProperties(&prop, index) != cudaSuccess) {
    cudaGetLastError();  // clear the error for later calls
    return std::nullopt;
  }
  return prop;
}
}  // namespace

void require_cuda_device(const Device& device) {
  if (!device_name(device.index).empty()) return;
  int found = 0;
  while (!device_name(found).empty()) ++found;
  if (found == 0)
    fail(ErrorCode::Unsupported,
         "device {}: no CUDA device here (no driver or no GPU); use --device cpu",
         device.to_string());
  fail(ErrorCode::Unsupported,
       "device {}: no such CUDA device here ({} found: cuda:0{}); use one of them or --device "
       "cpu",
       device.to_string(), found, found > 1 ? fmt::format(" to cuda:{}", found - 1) : "");
}

std::string device_name(int index) {
  const std::optional<cudaDeviceProp> prop = properties_of(index);
  return prop ? std::string(prop->name) : std::string();
}

std::optional<DeviceInfo> describe_cuda_device(int index) {
  const std::optional<cudaDeviceProp> prop = properties_of(index);
  int current = 0;
  if (!prop || cudaGetDevice(&current) != cudaSuccess) {
    cudaGetLastError();
    return std::nullopt;
  }
  DeviceInfo d;
  d.device = Device::cuda(index);
  d.name = prop->name;
  d.memory_bytes = static_cast<int64_t>(prop->totalGlobalMem);
  d.compute_major = prop->major;
  d.compute_minor = prop->minor;
  d.multiprocessors = prop->multiProcessorCount;
  std::size_t free = 0, total = 0;
  if (cudaSetDevice(index) == cudaSuccess && cudaMemGetInfo(&free, &total) == cudaSuccess)
    d.free_bytes = static_cast<int64_t>(free);
  cudaGetLastError();
  cudaSetDevice(current);
  return d;
}

std::vector<DeviceInfo> cuda_devices() {
  std::vector<DeviceInfo> out;
  int count = 0;
  if (cudaGetDeviceCount(&count) != cudaSuccess) cudaGetLastError();
  for (int i = 0; i < count; ++i)
    if (const std::optional<DeviceInfo> d = describe_cuda_device(i)) out.push_back(*d);
  return out;
}

struct GpuReconstruction::Impl {
  ReconstructionParams params;
  CameraRig rig;
  MapParams map_params;
  int64_t map_bytes = 0, total_bytes = 0;  ///< fixed allocations (the pools apart)

  // The map.
  std::array<Buffer<HashEntry>, kMaxLevels> entries;
  std::array<Buffer<int32_t>, kMaxLevels> excess_free;
  Buffer<int32_t> block_free;
  Buffer<int32_t> counters;
  // The pool's voxels and its blocks' metadata: committed up to the high-water mark (a block's
  // metadata is written when it is taken, as its voxels are cleared).
  GrowingArray<TsdfVoxel> tsdf;
  GrowingArray<ColorVoxel> color;
  GrowingArray<BlockMeta> meta;
  MutableMapView view;
  // The pool's counters as last read from the device (set_pool_counters).
  int32_t high_water = 0;
  int32_t free_count = 0;                         ///< free pool blocks
  int64_t blocks = 0;                             ///< in use
  std::vector<int64_t> level_blocks;              ///< in use, per level (finest first)
  std::array<int64_t, kMaxLevels> free_excess{};  ///< free overflow entries, per level
  bool memory_full = false;  ///< the pool stopped growing once: the device's memory is full
  int64_t dropped = 0;       ///< blocks dropped so far (the continued map's included)

  // Allocation.
  Buffer<int32_t> stamps;
  int32_t frame = 0;
  Buffer<unsigned long long> missing_keys;
  Buffer<BlockKey> missing_list;
  Buffer<BlockRef> visible;
  Buffer<AllocCounters> alloc_counters;
  PinnedBuffer<AllocCounters> host_counters;
  PinnedBuffer<int32_t> host_pool_counters;
  QueueMark fuse_start, allocated, integrated;  ///< the allocation's and integration's times
  // The model raycast last launched and not yet waited for. A frame does not wait for the
  // raycast it ends with: the host goes on to the next frame's upload (its copy into page-locked
  // memory) while the device raycasts, and the next frame waits after it (take_raycast) and
  // reports the raycast, the one its tracking uses.
  QueueMark ray_start, ray_end;
  PinnedBuffer<int32_t> host_hits;
  bool raycast_pending = false;
  // The super-blocks holding blocks (grown by insertions; on the host as of the last frame's
  // allocation) and the raycast's coarse occupancy grid over them.
  Buffer<kernels::SuperBlockBounds> occupancy_bounds;
  PinnedBuffer<kernels::SuperBlockBounds> host_bounds;
  kernels::SuperBlockBounds bounds;
  Buffer<int32_t> occupancy_cells;

  // The frame.
  PinnedBuffer<float> staged_depth;
  PinnedBuffer<Rgb8> staged_color;
  /// The frame's depth: one image, or two taken in turn where frames go up beside the raycast
  /// (the raycast after a frame starts its rays at that frame's depth while the next comes up).
  std::array<Buffer<float>, 2> depth_images;
  int depth_now = 0;  ///< the image holding the frame now
  Buffer<Rgb8> color_image;
  Buffer<uint32_t> packed_color;
  bool upload_beside = false;  ///< see set_upload_beside_raycast
  bool refine_beside = true;   ///< see set_refine_beside_raycast
  Stream frame_stream;         ///< the frames' uploads and pyramids, with upload_beside
  QueueMark frame_ready;       ///< the frame up and its pyramid made, on frame_stream

  // The model raycast and its pyramid; the frame's pyramid.
  Buffer<float> tile_z_min, tile_z_max;
  Buffer<Rgb8> model_colors;
  Buffer<int8_t> model_levels;
  Buffer<uint32_t> warp_nearest;  ///< the warp's nearest landings (float bits)
  Buffer<float> warped;           ///< the previous raycast seen from the new pose: fallback hints
  std::vector<ImageLevel> model, pyramid;
  Pose model_T_wc = Pose::Identity();
  bool has_model = false;
  Buffer<float> icp_partials;
  Buffer<double> icp_sums;
  Buffer<uint32_t> icp_done;
  PinnedBuffer<double> host_sums;
  PinnedBuffer<int32_t> host_valid_pixels;  ///< the frame's valid pixels, read with the sums
  bool gauss_newton_on_device = true;
  RaycastLaunch ray_launch;  ///< see set_split_marches, set_raycast_registers, set_queued_marches
  Buffer<int32_t> march_queue;          ///< see set_queued_marches
  int allocation_pixels = 1;            ///< see set_allocation_pixels
  Buffer<kernels::IcpState> icp_state;  ///< Gauss-Newton on the device: its state
  PinnedBuffer<kernels::IcpState> host_icp_state;
  Buffer<Rigid3f> icp_model_pose;  ///< world to the model's camera, for the passes on the device
  PinnedBuffer<Rigid3f> host_model_pose;
  bool icp_graph_on = false;  ///< see set_tracking_graph
  LaunchGraph icp_graph;      ///< the passes of Gauss-Newton on the device, recorded once

  // Refinement.
  Buffer<BlockRef> split_list;
  Buffer<BlockKey> merge_list;
  Buffer<unsigned long long> parent_keys;
  Buffer<BlockKey> parent_list;
  Buffer<int32_t> refine_counts;
  Buffer<MergeJob> merge_jobs;
  Buffer<SplitJob> split_jobs;
  // The host's page-locked copies: the counts and the lists' first entries come back in one
  // round trip, the jobs go down without one.
  PinnedBuffer<int32_t> host_refine_counts, host_map_counters;
  PinnedBuffer<BlockRef> host_splits;
  PinnedBuffer<BlockKey> host_merges;
  PinnedBuffer<MergeJob> host_merge_jobs;
  PinnedBuffer<SplitJob> host_split_jobs;
  int64_t refine_calls = 0;
  Stream refine_stream;  ///< refinement after the raycast (refine_and_raycast)

  std::vector<StampedPose> trajectory;
  std::vector<FrameStats> frames;
  TrackResult last_track;
  MotionPrior motion{params.track.constant_velocity};
  std::optional<Pose> resume_pose;  ///< the handed-over map's last pose: track from it

  Impl(const ReconstructionParams& p, const CameraRig& r, const VoxelBlockMap& host)
      : params(p), rig(r), map_params(host.params()) {
    params.map = map_params;
    params.map.validate();
    params.fusion.validate();
    params.raycast.validate();
    params.track.validate();
    rig.validate();
    if (params.device.is_cpu())
      fail(ErrorCode::InvalidArgument, "the CUDA loop needs a CUDA device, got {}",
           params.device.to_string());
    require_cuda_device(params.device);
    check_status(cudaSetDevice(params.device.index), "selecting the device");
    // The walk through the levels recurses (kernels::walk_segment_in): its depth grows with the
    // levels, so the compiler cannot size the stack; 1 KB a thread (the default) is too little
    // for four levels, or for three under compute-sanitizer.
    std::size_t stack = 0;
    check_status(cudaDeviceGetLimit(&stack, cudaLimitStackSize), "reading the stack size");
    if (stack < kStackBytes)
      check_status(cudaDeviceSetLimit(cudaLimitStackSize, kStackBytes), "setting the stack size");
    upload_map(host);
    allocate_frame_buffers();
    if (params.refine_after_raycast)
      log::warn_once("cuda.refine_after",
                     "refinement after the raycast (--refine-after-raycast) is not yet sound on a "
                     "GPU: on an H200, fr1/rpy ended with an illegal memory access in the raycast "
                     "(docs/cuda.md); leave it off for runs that matter");
  }

  void upload_map(const VoxelBlockMap& host) {
    const MutableMapView h = MapAccess::storage(host);
    const MapParams& mp = map_params;
    view = h;  // geometry; every pointer is replaced below
    const auto capacity = static_cast<std::size_t>(mp.max_blocks);
    for (int l = 0; l < mp.levels; ++l) {
      const auto n = static_cast<std::size_t>(h.read.level[l].entry_count);
      entries[l].assign(h.level[l].entries, n, &map_bytes);
      excess_free[l].assign(h.level[l].excess.items,
                            static_cast<std::size_t>(h.level[l].excess.capacity), &map_bytes);
      view.level[l].entries = entries[l].get();
      view.read.level[l].entries = entries[l].get();
    }
    block_free.assign(h.blocks.items, capacity, &map_bytes);
    const int32_t used = host.block_high_water();
    check_free_list(h.blocks, used);
    try {
      tsdf.reserve(capacity * kBlockVoxels, params.device.index);
      if (h.color != nullptr) color.reserve(capacity * kBlockVoxels, params.device.index);
      meta.reserve(capacity, params.device.index);
    } catch (const Error& e) {
      if (e.code() != ErrorCode::OutOfCapacity) throw;
      fail(ErrorCode::OutOfCapacity,
           "device {}: the map's pool of {} blocks (--max-blocks) does "
           "not fit: {}",
           params.device.to_string(), mp.max_blocks, e.what());
    }
    if (commit_pool(used) < used)
      fail(ErrorCode::OutOfCapacity,
           "device {}: out of memory for the {} blocks of the map handed over ({:.0f} MiB)",
           params.device.to_string(), used, static_cast<double>(used) * pool_block_bytes() / kMiB);
    view.tsdf = tsdf.get();
    view.color = h.color != nullptr ? color.get() : nullptr;
    const auto voxels = static_cast<std::size_t>(used) * kBlockVoxels;
    tsdf.upload(h.tsdf, voxels);
    if (view.color != nullptr) color.upload(h.color, voxels);
    meta.upload(h.meta, static_cast<std::size_t>(used));
    counters.reset(kCounters, &map_bytes);
    int32_t c[kCounters] = {};
    for (int l = 0; l < mp.levels; ++l) c[kExcessCount + l] = *h.level[l].excess.count;
    c[kBlockFreeCount] = *h.blocks.count;
    for (int l = 0; l < kMaxLevels; ++l) c[kLevelCount + l] = h.level_block_count[l];
    c[kHighWater] = *h.block_high_water;
    counters.upload(c, kCounters);
    for (int l = 0; l < mp.levels; ++l)
      view.level[l].excess = {excess_free[l].get(), counters.get() + kExcessCount + l,
                              h.level[l].excess.capacity};
    view.blocks = {block_free.get(), counters.get() + kBlockFreeCount, h.blocks.capacity};
    view.level_block_count = counters.get() + kLevelCount;
    view.block_high_water = counters.get() + kHighWater;
    view.meta = meta.get();
    view.read.tsdf = view.tsdf;
    view.read.color = view.color;
    view.read.meta = view.meta;
    set_pool_counters(c);
    bounds = kernels::super_block_bounds(h.meta, used, mp.levels);
    occupancy_bounds.assign(&bounds, 1, &total_bytes);
    dropped = host.dropped_blocks();
    total_bytes += map_bytes;
  }

  /// Device memory a pool block takes (voxels, colour, metadata).
  double pool_block_bytes() const {
    const std::size_t color_bytes = color.get() != nullptr ? sizeof(ColorVoxel) : 0;
    return static_cast<double>(kBlockVoxels * (sizeof(TsdfVoxel) + color_bytes) +
                               sizeof(BlockMeta));
  }
  static constexpr double kMiB = 1024.0 * 1024.0;

  /// Pool blocks [0, n) whose memory is committed.
  int64_t committed_blocks() const {
    std::size_t n = tsdf.committed_bytes() / (kBlockVoxels * sizeof(TsdfVoxel));
    if (color.get() != nullptr)
      n = std::min(n, color.committed_bytes() / (kBlockVoxels * sizeof(ColorVoxel)));
    return static_cast<int64_t>(std::min(n, meta.committed_bytes() / sizeof(BlockMeta)));
  }

  /// Commits the pool's memory (voxels and metadata) for pool blocks [0, n) where the device has
  /// the memory, keeping kPoolKeepsFreeBytes free; returns the pool blocks committed (fewer than n
  /// where the device is full).
  int64_t commit_pool(int64_t n) {
    const int64_t have = committed_blocks();
    if (n <= have) return have;
    const std::size_t free = free_device_memory();
    // Each array rounds up to the driver's granularity (2 MiB): room for that, so that the
    // arrays stop at the same block.
    constexpr std::size_t kRounding = 3 * (std::size_t{2} << 20);
    const std::size_t spare =
        free > kPoolKeepsFreeBytes + kRounding ? free - kPoolKeepsFreeBytes - kRounding : 0;
    n = std::min<int64_t>(
        n, have + static_cast<int64_t>(static_cast<double>(spare) / pool_block_bytes()));
    const auto blocks_n = static_cast<std::size_t>(n);
    tsdf.commit(blocks_n * kBlockVoxels, kPoolKeepsFreeBytes);
    if (color.get() != nullptr) color.commit(blocks_n * kBlockVoxels, kPoolKeepsFreeBytes);
    meta.commit(blocks_n, kPoolKeepsFreeBytes);
    return committed_blocks();
  }

  /// How many of `pops` more pool blocks the free list can give with their memory committed,
  /// committing it (as far as the device's memory allows). The list is a stack: the blocks freed
  /// below the high-water mark come off first, then new ones counting up from the mark (the part
  /// of the stack never popped; check_free_list), so `pops` need the pool committed up to the mark
  /// plus the pops beyond the freed blocks.
  int64_t room_for(int64_t pops) {
    pops = std::clamp<int64_t>(pops, 0, free_count);
    const int64_t fit = commit_for(pops);
    if (fit < pops) {
      memory_full = true;
      log::warn_once("cuda.memory_full",
                     "device {}: its memory is full ({:.0f} MiB committed to the map's pool): "
                     "blocks that do not fit are dropped (new ones) or wait (splits, merges), "
                     "counted in the stats; a coarser map (--voxel-size, --levels) or a shorter "
                     "--max-depth needs less",
                     params.device.to_string(), static_cast<double>(pool_bytes()) / kMiB);
    }
    return fit;
  }
  /// room_for without its warning: how many of `pops` (at most free_count) the pool can give
  /// with their memory committed, committing it.
  int64_t commit_for(int64_t pops) {
    const int64_t holes = std::max<int64_t>(0, free_count - (map_params.max_blocks - high_water));
    const int64_t committed =
        commit_pool(static_cast<int64_t>(high_water) + std::max<int64_t>(0, pops - holes));
    return std::min(pops, holes + committed - high_water);
  }

  /// The pool's counters from `c` (a copy of `counters`).
  void set_pool_counters(const int32_t* c) {
    for (int l = 0; l < map_params.levels; ++l) free_excess[l] = c[kExcessCount + l];
    high_water = c[kHighWater];
    free_count = c[kBlockFreeCount];
    blocks = map_params.max_blocks - free_count;
    level_blocks.assign(c + kLevelCount, c + kLevelCount + map_params.levels);
  }

  /// room_for's rule, checked once on the map handed over: the never-popped part of the free
  /// list (its bottom) holds the blocks from the high-water mark up, the lowest on top.
  void check_free_list(const FreeListView& list, int32_t high_water_mark) const {
    const int64_t untouched = map_params.max_blocks - high_water_mark;
    bool ok = untouched <= *list.count;
    for (int64_t i = 0; ok && i < untouched; ++i)
      ok = list.items[i] == map_params.max_blocks - 1 - i;
    if (!ok)
      fail(ErrorCode::InvalidArgument,
           "the map handed over has a free list out of order (the blocks above its high-water "
           "mark are not at the bottom, in order)");
  }

  int64_t pool_bytes() const {
    return static_cast<int64_t>(tsdf.committed_bytes() + color.committed_bytes() +
                                meta.committed_bytes());
  }

  void allocate_frame_buffers() {
    const PinholeCamera& cam = rig.depth_camera;
    const auto pixels = static_cast<std::size_t>(cam.width) * cam.height;
    const auto capacity = static_cast<std::size_t>(map_params.max_blocks);
    stamps.reset(capacity, &total_bytes);
    check_status(cudaMemset(stamps.get(), 0xFF, capacity * sizeof(int32_t)), "clearing stamps");
    // The missing set: twice the slots of its list, which holds what the pool could take in
    // one frame up to 2^20 blocks.
    const std::size_t list = std::min<std::size_t>(capacity, std::size_t{1} << 20);
    std::size_t slots = 1;
    while (slots < 2 * list) slots <<= 1;
    missing_keys.reset(slots, &total_bytes);
    missing_list.reset(list, &total_bytes);
    visible.reset(capacity, &total_bytes);
    alloc_counters.reset(1, &total_bytes);
    host_counters.reserve(1);
    host_hits.reserve(1);
    host_pool_counters.reserve(kCounters);
    depth_images[0].reset(pixels, &total_bytes);
    if (map_params.store_color && params.fusion.integrate_color) {
      color_image.reset(static_cast<std::size_t>(rig.color_camera.width) * rig.color_camera.height,
                        &total_bytes);
      packed_color.reset(pixels, &total_bytes);
    }
    // Pyramids: the frame's from the depth camera, the model's from its subsampled camera.
    const int levels = params.track.levels();
    pyramid.resize(static_cast<std::size_t>(levels));
    model.resize(static_cast<std::size_t>(levels));
    PinholeCamera fc = cam, mc = cam.subsampled(params.track.model_subsample);
    for (int l = 0; l < levels; ++l) {
      for (auto [level, c] : {std::pair{&pyramid[l], fc}, std::pair{&model[l], mc}}) {
        level->camera = c;
        const auto n = static_cast<std::size_t>(c.width) * c.height;
        level->depth.reset(n, &total_bytes);
        level->points.reset(n, &total_bytes);
        level->normals.reset(n, &total_bytes);
      }
      fc = fc.subsampled(2);
      mc = mc.subsampled(2);
    }
    const PinholeCamera& m0 = model[0].camera;
    const auto model_pixels = static_cast<std::size_t>(m0.width) * m0.height;
    model_colors.reset(model_pixels, &total_bytes);
    model_levels.reset(model_pixels, &total_bytes);
    warp_nearest.reset(model_pixels, &total_bytes);
    warped.reset(model_pixels, &total_bytes);
    const kernels::RangeTiles tiles =
        kernels::RangeTiles::covering(params.raycast.tuning.range_tile_px, m0);
    tile_z_min.reset(static_cast<std::size_t>(tiles.count()), &total_bytes);
    tile_z_max.reset(static_cast<std::size_t>(tiles.count()), &total_bytes);
    icp_partials.reset(static_cast<std::size_t>(icp_partials_size(static_cast<int64_t>(pixels))),
                       &total_bytes);
    icp_sums.reset(kernels::kIcpSums, &total_bytes);
    icp_done.reset(1, &total_bytes);
    check_status(cudaMemset(icp_done.get(), 0, sizeof(uint32_t)), "clearing the ICP counter");
    host_sums.reserve(kernels::kIcpSums);
    host_valid_pixels.reserve(1);
    icp_state.reset(1, &total_bytes);
    host_icp_state.reserve(1);
    icp_model_pose.reset(1, &total_bytes);
    host_model_pose.reserve(1);
    if (map_params.levels > 1) {
      // At most every visible block splits; their parents (each once) may merge.
      split_list.reset(list, &total_bytes);
      merge_list.reset(list, &total_bytes);
      parent_keys.reset(slots, &total_bytes);
      parent_list.reset(list, &total_bytes);
      refine_counts.reset(kRefineCounts, &total_bytes);
    }
  }

  /// Device buffer `b` holding at least `n` elements (grown by half again when short).
  template <typename T>
  void ensure(Buffer<T>& b, std::size_t n) {
    grow(b, n, &total_bytes);
  }

  /// The coarse occupancy grid over the super-blocks that hold blocks, as the CPU's raycaster
  /// builds it (the raycast clears and marks it), its cells in `cells` (grown to fit, counted in
  /// `*total` when not null), where asked for and not too large.
  kernels::CoarseOccupancy coarse_occupancy(Buffer<int32_t>& cells, int64_t* total) const {
    kernels::CoarseOccupancy occupancy;
    if (!params.raycast.tuning.coarse_skipping) return occupancy;
    occupancy = kernels::CoarseOccupancy::covering(
        bounds, view.read.level[map_params.levels - 1].block_size_m);
    const int64_t n = occupancy.cell_count();
    if (n > 0 && n <= kernels::CoarseOccupancy::kMaxCells) {
      grow(cells, static_cast<std::size_t>(n), total);
      occupancy.cells = cells.get();
    }
    return occupancy;
  }

  /// The model seen through `camera` from `T_wc` (GpuReconstruction::render): every ray marches
  /// over its range tile, as the CPU's Raycaster casts rays without hints.
  RaycastResult render(const PinholeCamera& camera, const Pose& T_wc,
                       const DepthRange& range) const {
    kernels::RangeTiles tiles =
        kernels::RangeTiles::covering(params.raycast.tuning.range_tile_px, camera);
    Buffer<float> z_min, z_max;
    z_min.reset(static_cast<std::size_t>(tiles.count()), nullptr);
    z_max.reset(static_cast<std::size_t>(tiles.count()), nullptr);
    tiles.z_min = z_min.get();
    tiles.z_max = z_max.get();
    Buffer<int32_t> cells;
    const kernels::RayMarchConstants k =
        kernels::march_constants(params.raycast, view.read, coarse_occupancy(cells, nullptr));
    const auto n = static_cast<std::size_t>(camera.width) * camera.height;
    RaycastImages images(n);
    Buffer<AllocCounters> hits;
    hits.reset(1, nullptr);
    check_status(cudaMemset(hits.get(), 0, sizeof(AllocCounters)), "render");
    // Without hints every ray marches, over ranges far longer than the model's: whole marches in
    // one kernel, whatever set_queued_marches and set_split_marches say of the model's raycast.
    // Split, a render's rays differ from the CPU's beyond what the raycast tests allow (the
    // desk pulled back 0.6 m: 94 of 52 145 rays hit by one only, 292 normals more than 2 degrees
    // apart).
    RaycastLaunch how = ray_launch;
    how.march_queue = nullptr;
    how.split_at_most = 0;
    cuda::raycast(view.read, high_water, camera, to_rigid3f(T_wc), range.min_m, range.max_m, tiles,
                  k, RayHintImages{}, images.view(), hits.get(), how);
    return download_raycast(camera, T_wc, view.color != nullptr, images.view());
  }

  /// Runs `check(device jobs, n)` on `jobs` and brings them back with the map's counters (into
  /// `c`) in one round trip on queue `q` (null: the default stream); keeps the jobs the check
  /// left `ok`.
  template <typename Job, typename Check>
  void check_jobs(std::vector<Job>& jobs, Buffer<Job>& device, PinnedBuffer<Job>& host, int32_t* c,
                  cudaStream_t q, const char* what, Check&& check) {
    ensure(device, jobs.size());
    send_jobs(jobs, device, host, q, what);
    check(device.get(), static_cast<int32_t>(jobs.size()));
    Job* staged = host.reserve(jobs.size());
    download_async(staged, device.get(), jobs.size(), what, q);
    download_async(c, counters.get(), kCounters, what, q);
    wait_for_queue(q, what);
    jobs.assign(staged, staged + jobs.size());
    std::erase_if(jobs, [](const Job& j) { return j.ok == 0; });
  }
  /// Sends `jobs` to the device (it holds as many) through page-locked `host` memory, on queue
  /// `q`: no wait.
  template <typename Job>
  static void send_jobs(const std::vector<Job>& jobs, Buffer<Job>& device, PinnedBuffer<Job>& host,
                        cudaStream_t q, const char* what) {
    Job* staged = host.reserve(jobs.size());
    std::copy(jobs.begin(), jobs.end(), staged);
    upload_async(device.get(), staged, jobs.size(), what, q);
  }

  /// Refines (see refine) and raycasts the model at `T_wc`, the frame just fused, in the order
  /// the parameters ask for. Refinement after the raycast goes on a stream of its own
  /// (refine_beside): its waits for the host's decisions overlap the raycast, and its passes
  /// that write the map wait for the raycast's end (ray_end). Else on the loop's stream after it.
  void refine_and_raycast(const Pose& T_wc, int32_t visible_count, FrameStats& s) {
    // Every `every_n_frames`-th call refines.
    const bool due = map_params.levels >= 2 && (refine_calls++ % params.refine.every_n_frames) == 0;
    if (!params.refine_after_raycast) {
      if (due) refine(T_wc, visible_count, nullptr, s);
      raycast_model(T_wc, true);
      return;
    }
    raycast_model(T_wc, true);
    if (!due) return;
    const cudaStream_t q = refine_beside ? refine_stream.get("refinement's stream") : nullptr;
    const LaunchesOn on(q);
    refine(T_wc, visible_count, q, s);
  }

  /// The CPU Refiner's refinement of the blocks this frame touched (the first `visible` of the
  /// visible list), on the device: decisions per block, then merges, then splits, queued on `q`
  /// (null: the default stream; else the launches' stream too, beside the model raycast).
  void refine(const Pose& T_wc, int32_t visible_count, cudaStream_t q, FrameStats& s) {
    Stopwatch stage;
    const RefineParams& rp = params.refine;
    RefineConstants k;
    k.levels = kernels::refine_levels(rp);
    k.det_cov = rp.criterion == RefineCriterion::DetCov;
    k.mu_m = map_params.truncation_m;
    k.min_weight = rp.min_weight;
    k.min_samples = rp.min_samples;
    k.min_updates = rp.min_updates;
    k.unmeshable_cells = rp.split_unmeshable_cells;
    k.unmeshable_min_weight = rp.unmeshable_min_weight;
    k.noise = rp.noise.value_or(rig.depth_noise);
    k.T_cw = to_rigid3f(T_wc.inverse());
    check_status(cudaMemsetAsync(refine_counts.get(), 0, kRefineCounts * sizeof(int32_t), q),
                 "clearing counters");
    check_status(cudaMemsetAsync(parent_keys.get(), 0xFF, parent_keys.size() * sizeof(uint64_t), q),
                 "clearing the parent set");
    const auto capacity = static_cast<int32_t>(split_list.size());
    const RefineLists lists{
        split_list.get(), merge_list.get(), capacity,
        BlockKeySet{parent_keys.get(), static_cast<uint32_t>(parent_keys.size() - 1),
                    parent_list.get(), static_cast<int32_t>(parent_list.size())},
        refine_counts.get()};
    split_candidates(view.read, visible.get(), visible_count, alloc_counters.get(), k, lists);
    // Each visible block has at most one parent: a bound for the parents split_candidates counts.
    merge_candidates(view.read, std::min(visible_count, lists.parents.capacity), k, lists);
    // The counts and the lists' first entries in one round trip; longer lists, rarely, in a second.
    const std::size_t head = std::min<std::size_t>(kRefineListHead, split_list.size());
    int32_t* counts = host_refine_counts.reserve(kRefineCounts);
    BlockRef* split_head = host_splits.reserve(head);
    BlockKey* merge_head = host_merges.reserve(head);
    download_async(counts, refine_counts.get(), 3, "refinement (counts)", q);
    download_async(split_head, split_list.get(), head, "refinement (split list)", q);
    download_async(merge_head, merge_list.get(), head, "refinement (merge list)", q);
    wait_for_queue(q, "refinement (candidates)");
    std::vector<BlockRef> splits(static_cast<std::size_t>(std::min(counts[0], capacity)));
    std::vector<BlockKey> merges(static_cast<std::size_t>(std::min(counts[2], capacity)));
    std::copy_n(split_head, std::min(head, splits.size()), splits.data());
    std::copy_n(merge_head, std::min(head, merges.size()), merges.data());
    if (splits.size() > head) split_list.download(splits.data() + head, splits.size() - head, head);
    if (merges.size() > head) merge_list.download(merges.data() + head, merges.size() - head, head);

    // Merges, in key order (the CPU's merge_blocks).
    std::sort(merges.begin(), merges.end());
    std::vector<MergeJob> mj(merges.size());
    for (std::size_t i = 0; i < merges.size(); ++i) mj[i].parent = merges[i];
    // Splits, in key order, once per block (the CPU's split_blocks).
    std::sort(splits.begin(), splits.end(), [](const BlockRef& a, const BlockRef& b) {
      return BlockKey{a.pos, a.level} < BlockKey{b.pos, b.level};
    });
    splits.erase(std::unique(splits.begin(), splits.end(),
                             [](const BlockRef& a, const BlockRef& b) { return a.ptr == b.ptr; }),
                 splits.end());
    std::vector<SplitJob> sj(splits.size());
    for (std::size_t i = 0; i < splits.size(); ++i) sj[i].parent = splits[i];
    int32_t* c = host_map_counters.reserve(kCounters);
    const bool at_once = refine_at_once(mj, sj, rp.split_weight_scale, q);
    if (at_once)
      download_async(counts + kMergesOk, refine_counts.get() + kMergesOk, 2,
                     "refinement (the jobs done)", q);
    else
      refine_checked(mj, sj, rp.split_weight_scale, q, c, s);
    // The pool's counters after the edits (a round trip).
    download_async(c, counters.get(), kCounters, "refinement (the pool's counters)", q);
    wait_for_queue(q, "refinement (the pool's counters)");
    set_pool_counters(c);
    if (at_once) {
      s.merges = counts[kMergesOk];
      s.splits = counts[kSplitsOk];
    }
    s.refine_ms = stage.lap_ms();
  }

  /// Refinement's writes queued at once, without reading the checks back (two round trips a
  /// refinement fewer than refine_checked), where the pool and the overflow lists have room for
  /// every job as the host last read them: a merge takes a block before it frees 8, a split 8
  /// blocks and 8 overflow entries of the level below, none counting what the merges free. The
  /// jobs whose check fails are skipped on the device, and their count comes back with the pool's
  /// counters. Returns false, doing nothing, where room may lack (refine_checked then decides job
  /// by job). The same jobs in the same order as refine_checked: the same map.
  bool refine_at_once(const std::vector<MergeJob>& mj, std::vector<SplitJob>& sj,
                      float weight_scale, cudaStream_t q) {
    if (mj.empty() && sj.empty()) return true;
    kernels::SplitRoom room{free_count - static_cast<int64_t>(mj.size()), free_excess};
    for (const SplitJob& j : sj)
      if (!room.take(j.parent.level)) return false;
    const auto pops = static_cast<int64_t>(mj.size() + kBlockChildren * sj.size());
    if (pops > free_count || commit_for(pops) < pops) return false;
    by_parent_level(sj);
    if (!mj.empty()) {
      ensure(merge_jobs, mj.size());
      send_jobs(mj, merge_jobs, host_merge_jobs, q, "merging (the jobs)");
      merge_lookup(view.read, merge_jobs.get(), static_cast<int32_t>(mj.size()),
                   refine_counts.get() + kMergesOk);
    }
    if (!sj.empty()) {
      ensure(split_jobs, sj.size());
      send_jobs(sj, split_jobs, host_split_jobs, q, "splitting (the jobs)");
    }
    after_raycast(q);
    if (!mj.empty()) merge_apply(view, merge_jobs.get(), static_cast<int32_t>(mj.size()));
    if (!sj.empty()) {
      // After the merges: a merged parent's children are no longer blocks to split.
      split_check(view.read, split_jobs.get(), static_cast<int32_t>(sj.size()),
                  refine_counts.get() + kSplitsOk);
      split_levels(sj, weight_scale);
    }
    return true;
  }

  /// Refinement's writes job by job: each check read back, the jobs that pass and fit queued
  /// (those the pool or the overflow lists lack room for wait, counted in `s`).
  void refine_checked(std::vector<MergeJob>& mj, std::vector<SplitJob>& sj, float weight_scale,
                      cudaStream_t q, int32_t* c, FrameStats& s) {
    if (!mj.empty()) {
      check_jobs(mj, merge_jobs, host_merge_jobs, c, q, "merging (looking up)",
                 [&](MergeJob* jobs, int32_t n) { merge_lookup(view.read, jobs, n); });
      // A merge needs a block before it frees 8 (room_for commits their memory).
      set_pool_counters(c);
      const int64_t room = room_for(static_cast<int64_t>(mj.size()));
      if (static_cast<int64_t>(mj.size()) > room) {
        s.refine_waiting += static_cast<int64_t>(mj.size()) - room;
        mj.resize(static_cast<std::size_t>(room));
      }
      send_jobs(mj, merge_jobs, host_merge_jobs, q, "merging (the jobs)");
      after_raycast(q);
      merge_apply(view, merge_jobs.get(), static_cast<int32_t>(mj.size()));
      s.merges = static_cast<int64_t>(mj.size());
    }
    if (sj.empty()) return;
    check_jobs(sj, split_jobs, host_split_jobs, c, q, "splitting (checking)",
               [&](SplitJob* jobs, int32_t n) { split_check(view.read, jobs, n); });
    set_pool_counters(c);
    kernels::SplitRoom room{free_count, free_excess};
    std::vector<SplitJob> go;
    for (const SplitJob& j : sj) {
      if (room.take(j.parent.level))
        go.push_back(j);
      else
        ++s.refine_waiting;
    }
    // The children's memory (room_for commits it); splits beyond it wait too.
    const auto fit = static_cast<std::size_t>(
        room_for(static_cast<int64_t>(go.size()) * kBlockChildren) / kBlockChildren);
    if (fit < go.size()) {
      s.refine_waiting += static_cast<int64_t>(go.size() - fit);
      go.resize(fit);
    }
    if (s.refine_waiting > 0 && !memory_full)
      log::warn_once("cuda.split_waiting",
                     "device map: voxel block pool or hash overflow list too small for all "
                     "splits: splits wait and are counted in stats; raise --max-blocks");
    by_parent_level(go);
    if (!go.empty()) {
      send_jobs(go, split_jobs, host_split_jobs, q, "splitting (the jobs)");
      after_raycast(q);
      split_levels(go, weight_scale);
    }
    s.splits = static_cast<int64_t>(go.size());
  }

  /// Refinement's passes that write the map, on queue `q`, start after the model raycast when
  /// they run beside it (`q` not null); the look-ups and checks before them only read it.
  void after_raycast(cudaStream_t q) {
    if (q != nullptr) ray_end.order_before(q, "refinement");
  }

  /// One parent level at a time, finest first (a split reads its level while it writes the next
  /// finer one): `jobs` in that order, key order within a level.
  static void by_parent_level(std::vector<SplitJob>& jobs) {
    std::stable_sort(jobs.begin(), jobs.end(), [](const SplitJob& a, const SplitJob& b) {
      return a.parent.level < b.parent.level;
    });
  }
  /// Splits `jobs` (by_parent_level's order, on the device in split_jobs), level by level, and
  /// returns their parents' blocks.
  void split_levels(const std::vector<SplitJob>& jobs, float weight_scale) {
    std::size_t begin = 0;
    while (begin < jobs.size()) {
      std::size_t end = begin;
      while (end < jobs.size() && jobs[end].parent.level == jobs[begin].parent.level) ++end;
      split_apply_level(view, split_jobs.get() + begin, static_cast<int32_t>(end - begin),
                        weight_scale);
      begin = end;
    }
    split_finish(view, split_jobs.get(), static_cast<int32_t>(jobs.size()));
  }

  /// The frame's depth (and colour) on the device; returns the fusion's input views. Beside
  /// the raycast (upload_beside), the frame goes up on the frames' stream, and with `tracked` its
  /// pyramid is made there too; frame_ready marks the end.
  IntegrationFrame upload_frame(const RgbdFrame& f, const Pose& T_wc, bool tracked) {
    const PinholeCamera& cam = rig.depth_camera;
    if (f.depth_m.width() != cam.width || f.depth_m.height() != cam.height)
      fail(ErrorCode::InvalidArgument, "frame {}: the depth image is {}x{} but the camera is {}x{}",
           f.index, f.depth_m.width(), f.depth_m.height(), cam.width, cam.height);
    const FusionInput in = fusion_input(rig, f, T_wc);
    validate_input(in);
    // Depth view and constants as the CPU builds them (no colour: registered colour is packed on
    // the device, not the host); the image pointers are the device's.
    FusionInput depth_only = in;
    depth_only.color = nullptr;
    std::vector<uint32_t> unused;
    IntegrationFrame frame = integration_frame(depth_only, params.fusion, map_params, &unused);
    const std::size_t pixels = f.depth_m.size();
    const bool with_color = color_image.size() > 0 && in.color != nullptr;
    const PinholeCamera& cc = rig.color_camera;
    if (with_color && (f.color.width() != cc.width || f.color.height() != cc.height))
      fail(ErrorCode::InvalidArgument,
           "frame {}: the colour image is {}x{} but the colour camera is {}x{}", f.index,
           f.color.width(), f.color.height(), cc.width, cc.height);
    // Beside the raycast: into the other depth image (the raycast in flight reads this one), on
    // the frames' stream (pack_color's launch and the pyramid's too).
    cudaStream_t q = nullptr;
    if (upload_beside) {
      depth_now ^= 1;
      q = frame_stream.get("the frames' stream");
    }
    const LaunchesOn on(q);
    float* staged = staged_depth.reserve(pixels);
    parallel_copy(staged, f.depth_m.data(), pixels * sizeof(float));
    upload_async(frame_depth(), staged, pixels, "uploading the depth", q);
    frame.depth.depth_m.data = frame_depth();
    if (with_color) {
      const std::size_t n = f.color.size();
      Rgb8* staged_c = staged_color.reserve(n);
      parallel_copy(staged_c, f.color.data(), n * sizeof(Rgb8));
      upload_async(color_image.get(), staged_c, n, "uploading the colour", q);
      kernels::ColorFrameView& color = frame.color;
      color.image = {color_image.get(), cc.width, cc.height};
      color.camera = cc;
      color.T_color_depth = to_rigid3f(rig.T_color_depth);
      color.registered = rig.color_registered();
      if (color.registered) {
        pack_color(color_image.get(), packed_color.get(), static_cast<int64_t>(n));
        color.packed = packed_color.get();
      }
    }
    if (upload_beside) {
      if (tracked) make_pyramid(q);
      frame_ready.record("the frame's upload", q);
    }
    return frame;
  }

  /// The depth image holding the frame now.
  float* frame_depth() const { return depth_images[static_cast<std::size_t>(depth_now)].get(); }

  /// The frame's pyramid for tracking (bilateral filter, downsampling, points and normals) and
  /// its count of valid pixels, which comes back with tracking's results, queued on `q` (null:
  /// the default stream).
  void make_pyramid(cudaStream_t q) {
    const TrackParams& tp = params.track;
    const DepthRange& range = params.fusion.depth_range;
    const float lo = std::max(range.min_m, std::numeric_limits<float>::min());
    const float inv_px = 1.0f / (2.0f * tp.bilateral_sigma_px * tp.bilateral_sigma_px);
    const float inv_d = 1.0f / (2.0f * tp.bilateral_sigma_depth_m * tp.bilateral_sigma_depth_m);
    const PinholeCamera& cam = pyramid[0].camera;
    filter_depth(frame_depth(), pyramid[0].depth.get(), cam.width, cam.height,
                 tp.bilateral_radius_px, inv_px, inv_d, lo, range.max_m);
    int32_t* valid = &alloc_counters.get()->icp_valid_pixels;
    check_status(cudaMemsetAsync(valid, 0, sizeof(int32_t), q), "clearing counters");
    for (std::size_t l = 0; l < pyramid.size(); ++l) {
      ImageLevel& P = pyramid[l];
      if (l > 0)
        downsample_depth(pyramid[l - 1].depth.get(), P.depth.get(), P.camera.width, P.camera.height,
                         tp.max_depth_jump_ratio);
      points_and_normals(P.depth.get(), P.camera, tp.max_depth_jump_ratio, P.points.get(),
                         P.normals.get(), l == 0 ? valid : nullptr);
    }
    download_async(host_valid_pixels.reserve(1), valid, 1, "tracking (preprocessing)", q);
  }

  /// Allocates and integrates the frame; returns how many blocks it saw (the first of the
  /// visible list: the blocks refinement looks at).
  int32_t fuse(const IntegrationFrame& f, const Pose& T_wc, FrameStats& s) {
    if (upload_beside) frame_ready.order_before(nullptr, "fusion (the frame's upload)");
    fuse_start.record("timing the allocation");
    if (++frame == INT32_MAX) {
      check_status(cudaMemset(stamps.get(), 0xFF, stamps.size() * sizeof(int32_t)),
                   "clearing stamps");
      frame = 0;
    }
    check_status(cudaMemsetAsync(alloc_counters.get(), 0, sizeof(AllocCounters)),
                 "clearing counters");
    check_status(cudaMemsetAsync(missing_keys.get(), 0xFF, missing_keys.size() * sizeof(uint64_t)),
                 "clearing the missing set");
    const int64_t free_blocks = map_params.max_blocks - blocks;
    BlockKeySet missing{missing_keys.get(), static_cast<uint32_t>(missing_keys.size() - 1),
                        missing_list.get(),
                        static_cast<int32_t>(std::min<int64_t>(
                            free_blocks, static_cast<int64_t>(missing_list.size())))};
    const Rigid3f T = to_rigid3f(T_wc);
    find_blocks(view.read, f.depth, T, map_params.truncation_m, stamps.get(), frame, missing,
                visible.get(), alloc_counters.get(), allocation_pixels);
    AllocCounters* c = host_counters.reserve(1);
    copy_to_host(c, alloc_counters.get(), sizeof(AllocCounters),
                 "allocation (reading the counters)");
    const int32_t found = c->visible;
    // What the pool can take with its memory committed (room_for commits it).
    const int32_t can_insert = std::min(c->missing, missing.capacity);
    const auto to_insert = static_cast<int32_t>(room_for(can_insert));
    const int64_t beyond = c->missing - to_insert;
    insert_blocks(view, missing, to_insert, visible.get(), stamps.get(), frame,
                  alloc_counters.get(), occupancy_bounds.get());
    allocated.record("timing the allocation");
    cuda::integrate(view, visible.get(), found + to_insert, alloc_counters.get(), f.depth, f.color,
                    f.constants);
    integrated.record("timing the integration");
    // The counters, the pool's counters and the super-blocks' bounds in one round trip (the
    // stages' times are the device's, between the marks).
    int32_t* pc = host_pool_counters.reserve(kCounters);
    kernels::SuperBlockBounds* hb = host_bounds.reserve(1);
    download_async(c, alloc_counters.get(), 1, "reading the counters");
    download_async(pc, counters.get(), kCounters, "reading the pool's counters");
    download_async(hb, occupancy_bounds.get(), 1, "reading the super-blocks' bounds");
    wait_for_device("integration");
    s.allocate_ms = allocated.ms_since(fuse_start, "timing the allocation");
    s.integrate_ms = integrated.ms_since(allocated, "timing the integration");
    set_pool_counters(pc);
    bounds = *hb;
    s.valid_pixels = c->valid_pixels;
    s.visible_blocks = c->visible;
    s.new_blocks = c->inserted;
    s.dropped_blocks = c->hash_full + c->pool_full + beyond;
    dropped += s.dropped_blocks;
    if (s.dropped_blocks > can_insert - to_insert)  // more than the device's memory dropped
      log::warn_once("cuda.dropped",
                     "device map: {} blocks dropped this frame (pool or hash table full); raise "
                     "--max-blocks, --hash-buckets or --hash-excess",
                     s.dropped_blocks);
    return c->visible;
  }

  /// Raycasts the model at `T_wc`; `frame_hint`: the frame on the device was taken there, its
  /// depth tells the rays where to start. Launched only: take_raycast waits for it.
  void raycast_model(const Pose& T_wc, bool frame_hint) {
    const ImageLevel& m0 = model[0];
    kernels::RangeTiles tiles =
        kernels::RangeTiles::covering(params.raycast.tuning.range_tile_px, m0.camera);
    tiles.z_min = tile_z_min.get();
    tiles.z_max = tile_z_max.get();
    const kernels::RayMarchConstants k = kernels::march_constants(
        params.raycast, view.read, coarse_occupancy(occupancy_cells, &total_bytes));
    const kernels::RaycastOutputView out{m0.depth.get(), m0.points.get(), m0.normals.get(),
                                         model_colors.get(), model_levels.get()};
    ray_start.record("timing the raycast");
    check_status(cudaMemsetAsync(&alloc_counters.get()->raycast_hits, 0, sizeof(int32_t)),
                 "clearing counters");
    const DepthRange& range = params.fusion.depth_range;
    RayHintImages hint;
    if (frame_hint) hint = {frame_depth(), rig.depth_camera.width, params.track.model_subsample};
    if (has_model && params.previous_raycast_hints) {
      // The previous raycast (still in the model's images) seen from here: where the frame has
      // no depth, or the search at it fails, the surface is usually where the last raycast saw it.
      const PinholeCamera& c = m0.camera;
      warp_depth(kernels::WarpView::of(to_rigid3f(T_wc.inverse()), c, map_params.truncation_m),
                 m0.depth.get(), m0.points.get(), m0.normals.get(),
                 static_cast<int64_t>(c.width) * c.height, warp_nearest.get(), warped.get());
      hint.fallback_m = warped.get();
    }
    if (has_model) hint.levels = model_levels.get();  // the surface's levels a raycast ago
    cuda::raycast(view.read, high_water, m0.camera, to_rigid3f(T_wc), range.min_m, range.max_m,
                  tiles, k, hint, out, alloc_counters.get(), ray_launch);
    download_async(host_hits.reserve(1), &alloc_counters.get()->raycast_hits, 1, "raycast");
    ray_end.record("timing the raycast");
    raycast_pending = true;
    model_T_wc = T_wc;
    has_model = true;
  }

  /// Waits for the raycast launched last (if not yet waited for) and adds it to `s`: its time on
  /// the device and its hits.
  void take_raycast(FrameStats& s) {
    if (!raycast_pending) return;
    ray_end.wait("raycast");
    raycast_pending = false;
    s.raycast_ms += ray_end.ms_since(ray_start, "timing the raycast");
    s.raycast_hits = *host_hits.reserve(1);
  }

  TrackResult track(const Pose& T_init) {
    TrackResult result;
    Stopwatch watch;
    const TrackParams& tp = params.track;
    // The frame's pyramid: made now, or (upload_beside) already on the frames' stream, which the
    // passes then wait for.
    if (upload_beside)
      frame_ready.order_before(nullptr, "tracking (the frame's pyramid)");
    else
      make_pyramid(nullptr);
    for (std::size_t l = 1; l < model.size(); ++l) {
      const ImageLevel& in = model[l - 1];
      ImageLevel& out = model[l];
      downsample_model(in.points.get(), in.normals.get(), in.depth.get(), in.camera.width,
                       out.points.get(), out.normals.get(), out.depth.get(), out.camera.width,
                       out.camera.height, tp.max_depth_jump_ratio);
    }
    // The valid pixels come back with the first pass's sums (or the state): no round trip here.
    int32_t* valid_pixels = host_valid_pixels.reserve(1);
    result.preprocess_ms = watch.lap_ms();
    const Rigid3f T_model_cw = to_rigid3f(model_T_wc.inverse());
    // A pass's constants at pyramid level `level` (the pose: `T_wc`, unless the device's state
    // gives it).
    auto pass_at = [&](int level, const Rigid3f& T_wc) {
      return kernels::IcpPass(T_wc, T_model_cw, model[static_cast<std::size_t>(level)].camera,
                              tp.max_distance_m * static_cast<float>(1 << level), tp);
    };
    double* sums = host_sums.reserve(kernels::kIcpSums);
    const icp::Reduce reduce = [&](int level, const Pose& T) {
      const ImageLevel& F = pyramid[static_cast<std::size_t>(level)];
      const ImageLevel& M = model[static_cast<std::size_t>(level)];
      icp_reduce(pass_at(level, to_rigid3f(T)), F.points.get(), F.normals.get(),
                 static_cast<int64_t>(F.camera.width) * F.camera.height, M.points.get(),
                 M.normals.get(), icp_partials.get(), icp_done.get(), icp_sums.get(), sums);
      icp::Sums out;
      std::copy(sums, sums + kernels::kIcpSums, out.v);
      return out;
    };
    if (!gauss_newton_on_device) {
      const icp::Alignment a = icp::align(tp, reduce, T_init);
      wait_for_device("tracking");  // the valid pixels' copy is done (without passes too)
      icp::judge_alignment(tp, a, reduce, *valid_pixels, T_init, &result);
      result.icp_ms = watch.lap_ms();
      return result;
    }
    // Gauss-Newton on the device: every level's passes launched at once, each stepping the state
    // where its sums end (a pass at a stopped level does nothing); the state is read back once.
    // Recorded as a graph, the passes read the model's pose from device memory too: their
    // arguments are then every frame's.
    kernels::IcpState* state = host_icp_state.reserve(1);
    *state = kernels::icp_start(icp::to_posed(T_init));
    upload_async(icp_state.get(), state, 1, "tracking (Gauss-Newton's start)");
    const Rigid3f* model_pose_on_device = nullptr;
    if (icp_graph_on) {
      Rigid3f* model_pose = host_model_pose.reserve(1);
      *model_pose = T_model_cw;
      upload_async(icp_model_pose.get(), model_pose, 1, "tracking (the model's pose)");
      model_pose_on_device = icp_model_pose.get();
    }
    const auto passes = [&] {
      for (int level = tp.levels() - 1; level >= 0; --level) {
        const ImageLevel& F = pyramid[static_cast<std::size_t>(level)];
        const ImageLevel& M = model[static_cast<std::size_t>(level)];
        const kernels::IcpPass pass = pass_at(level, Rigid3f{});
        for (int it = 0; it < tp.iterations[static_cast<std::size_t>(level)]; ++it)
          icp_pass_on_device(pass, F.points.get(), F.normals.get(),
                             static_cast<int64_t>(F.camera.width) * F.camera.height, M.points.get(),
                             M.normals.get(), icp_partials.get(), icp_done.get(), icp_sums.get(),
                             icp_state.get(), model_pose_on_device, level, tp.convergence_step);
      }
    };
    if (icp_graph_on)
      icp_graph.run(passes, "tracking (the passes' graph)");
    else
      passes();
    copy_to_host(state, icp_state.get(), sizeof(kernels::IcpState), "tracking (Gauss-Newton)");
    // A blocking copy waits for the default stream alone: the valid pixels came on the frames'.
    if (upload_beside) frame_ready.wait("tracking (the valid pixels)");
    icp::judge_alignment(tp, icp::alignment_of(*state), reduce, *valid_pixels, T_init, &result);
    result.icp_ms = watch.lap_ms();
    return result;
  }

  const FrameStats& record(const RgbdFrame& f, const Pose& T_wc, const Stopwatch& total,
                           FrameStats& s) {
    s.index = f.index;
    s.timestamp_s = f.timestamp_s;
    s.total_ms = total.elapsed_ms();
    trajectory.push_back({f.timestamp_s, T_wc});
    frames.push_back(s);
    return frames.back();
  }
};

GpuReconstruction::GpuReconstruction(const ReconstructionParams& params, const CameraRig& rig)
    : GpuReconstruction(params, rig, VoxelBlockMap(params.map)) {}

GpuReconstruction::GpuReconstruction(const ReconstructionParams& params, const CameraRig& rig,
                                     const VoxelBlockMap& map, const MapSession& session)
    : impl_(std::make_unique<Impl>(params, rig, map)) {
  if (session.frames_fused < 0)
    fail(ErrorCode::InvalidArgument, "a map session of {} frames", session.frames_fused);
  impl_->resume_pose = session.last_pose;
  impl_->refine_calls = session.frames_fused;
}

GpuReconstruction::~GpuReconstruction() = default;

const FrameStats& GpuReconstruction::integrate(const RgbdFrame& frame, const Pose& T_wc) {
  Impl& m = *impl_;
  FrameStats s;
  m.last_track = TrackResult{};
  m.last_track.quality = TrackingQuality::Good;  // a given pose
  m.last_track.T_wc = T_wc;
  Stopwatch total;
  const IntegrationFrame f = m.upload_frame(frame, T_wc, false);
  s.upload_ms = total.elapsed_ms();
  m.take_raycast(s);  // the frame before's, which the upload overlapped
  const int32_t visible = m.fuse(f, T_wc, s);
  m.refine_and_raycast(T_wc, visible, s);
  return m.record(frame, T_wc, total, s);
}

const FrameStats& GpuReconstruction::track_and_integrate(const RgbdFrame& frame,
                                                         const Pose& T_wc_first) {
  Impl& m = *impl_;
  if (m.trajectory.empty() && !m.resume_pose) {
    m.motion.restart();
    return integrate(frame, T_wc_first);
  }
  FrameStats s;
  Stopwatch total;
  const Pose T_prev = m.trajectory.empty() ? *m.resume_pose : m.trajectory.back().T_wc;
  const IntegrationFrame f0 = m.upload_frame(frame, T_prev, true);
  s.upload_ms = total.elapsed_ms();
  m.take_raycast(s);  // the model tracked against, made after the frame before
  Stopwatch stage;
  if (!m.has_model || !m.model_T_wc.isApprox(T_prev)) {
    m.raycast_model(T_prev, false);
    m.take_raycast(s);
    stage.restart();
  }
  m.last_track = m.track(m.motion.start(T_prev));
  s.take_track(m.last_track);
  s.track_ms = stage.lap_ms();
  const Pose T_wc = m.motion.keep(T_prev, m.last_track);
  if (m.last_track.quality == TrackingQuality::Lost) {
    s.fused = false;
    s.valid_pixels = m.last_track.valid_pixels;
    return m.record(frame, T_wc, total, s);
  }
  // The integration constants at the tracked pose (the images are already on the device).
  IntegrationFrame f = f0;
  f.constants.T_cw = to_rigid3f(T_wc.inverse());
  const int32_t visible = m.fuse(f, T_wc, s);
  m.refine_and_raycast(T_wc, visible, s);
  return m.record(frame, T_wc, total, s);
}

void GpuReconstruction::synchronize() const {
  wait_for_device("waiting for the device");
}

const std::vector<StampedPose>& GpuReconstruction::trajectory() const {
  return impl_->trajectory;
}
const std::vector<FrameStats>& GpuReconstruction::frames() const {
  return impl_->frames;
}
const TrackResult& GpuReconstruction::last_track() const {
  return impl_->last_track;
}
void GpuReconstruction::set_gauss_newton_on_device(bool on) {
  impl_->gauss_newton_on_device = on;
}
void GpuReconstruction::set_split_marches(int at_most) {
  if (at_most < 0 || at_most > 32)
    fail(ErrorCode::InvalidArgument, "split marches: at most {} rays a warp is not in [0, 32]",
         at_most);
  impl_->ray_launch.split_at_most = at_most;
}
void GpuReconstruction::set_queued_marches(bool on) {
  Impl& m = *impl_;
  const PinholeCamera& c = m.model[0].camera;
  const auto pixels = static_cast<std::size_t>(c.width) * c.height;
  if (on && m.march_queue.size() == 0) m.march_queue.reset(pixels + 2, &m.total_bytes);
  m.ray_launch.march_queue = on ? m.march_queue.get() : nullptr;
  m.ray_launch.march_queue_pixels = on ? static_cast<int64_t>(pixels) : 0;
}
void GpuReconstruction::set_raycast_registers(int at_most) {
  if (at_most != 0 && std::find(std::begin(kRaycastRegisterCaps), std::end(kRaycastRegisterCaps),
                                at_most) == std::end(kRaycastRegisterCaps))
    fail(ErrorCode::InvalidArgument,
         "raycast registers: at most {} a thread is not 0 (the compiler's choice) or one of {}",
         at_most, fmt::join(kRaycastRegisterCaps, ", "));
  impl_->ray_launch.registers_at_most = at_most;
}
void GpuReconstruction::set_tracking_graph(bool on) {
  impl_->icp_graph_on = on;
}
void GpuReconstruction::set_upload_beside_raycast(bool on) {
  Impl& m = *impl_;
  if (on && m.depth_images[1].size() == 0)
    m.depth_images[1].reset(m.depth_images[0].size(), &m.total_bytes);
  m.upload_beside = on;
}
void GpuReconstruction::set_refine_beside_raycast(bool on) {
  impl_->refine_beside = on;
}
void GpuReconstruction::set_allocation_pixels(int per_thread) {
  if (per_thread != 1 && per_thread != 2 && per_thread != 4)
    fail(ErrorCode::InvalidArgument, "allocation: {} pixels a thread is not 1, 2 (2x1) or 4 (2x2)",
         per_thread);
  impl_->allocation_pixels = per_thread;
}
int GpuReconstruction::raycast_registers() const {
  return raycast_kernel_registers(impl_->ray_launch);
}

const MapParams& GpuReconstruction::map_params() const {
  return impl_->map_params;
}
int64_t GpuReconstruction::blocks_in_use() const {
  return impl_->blocks;
}
int64_t GpuReconstruction::dropped_blocks() const {
  return impl_->dropped;
}
int64_t GpuReconstruction::map_memory_bytes() const {
  return impl_->map_bytes + impl_->pool_bytes();
}
int64_t GpuReconstruction::device_memory_bytes() const {
  return impl_->total_bytes + impl_->pool_bytes();
}

std::unique_ptr<VoxelBlockMap> GpuReconstruction::download_map() const {
  auto host = std::make_unique<VoxelBlockMap>(impl_->map_params);
  download_map(*host);
  return host;
}

void GpuReconstruction::download_map(VoxelBlockMap& host) const {
  const Impl& m = *impl_;
  const MapParams& hp = host.params();
  if (!hp.shape_difference(m.map_params).empty() || hp.max_blocks != m.map_params.max_blocks ||
      hp.buckets_per_level != m.map_params.buckets_per_level ||
      hp.excess_per_level != m.map_params.excess_per_level ||
      hp.store_color != m.map_params.store_color)
    fail(ErrorCode::InvalidArgument, "download_map: the host map differs from the device's: {}",
         hp.shape_difference(m.map_params).empty() ? "its capacities"
                                                   : hp.shape_difference(m.map_params));
  const MutableMapView h = MapAccess::storage(host);
  MapAccess::add_dropped_blocks(host, m.dropped - host.dropped_blocks());
  int32_t c[kCounters];
  m.counters.download(c, kCounters);
  for (int l = 0; l < m.map_params.levels; ++l) {
    m.entries[l].download(h.level[l].entries, m.entries[l].size());
    m.excess_free[l].download(h.level[l].excess.items, m.excess_free[l].size());
    *h.level[l].excess.count = c[kExcessCount + l];
  }
  m.block_free.download(h.blocks.items, m.block_free.size());
  *h.blocks.count = c[kBlockFreeCount];
  for (int l = 0; l < kMaxLevels; ++l) h.level_block_count[l] = c[kLevelCount + l];
  // Past its high-water mark a map's metadata is free (level -1): the device holds none there,
  // and the host's is cleared up to its own mark.
  const auto used = static_cast<std::size_t>(c[kHighWater]);
  const auto host_used = static_cast<std::size_t>(*h.block_high_water);
  *h.block_high_water = c[kHighWater];
  m.meta.download(h.meta, used);
  if (host_used > used) std::fill(h.meta + used, h.meta + host_used, BlockMeta{});
  m.tsdf.download(h.tsdf, used * kBlockVoxels);
  if (h.color != nullptr && m.view.color != nullptr) m.color.download(h.color, used * kBlockVoxels);
}

std::vector<BlockRef> GpuReconstruction::allocated_blocks(int32_t* high_water) const {
  const Impl& m = *impl_;
  int32_t c[kCounters];
  m.counters.download(c, kCounters);
  std::vector<BlockMeta> meta(static_cast<std::size_t>(c[kHighWater]));
  m.meta.download(meta.data(), meta.size());
  if (high_water != nullptr) *high_water = c[kHighWater];
  return hivox::allocated_blocks(meta.data(), c[kHighWater]);
}

TriangleMesh GpuReconstruction::extract_mesh(const MeshParams& params,
                                             RemovedPieces* removed) const {
  params.validate();
  return on_device_else_host(
      "mesh", [&] { return mesh_on_device(params, removed); },
      [&] { return hivox::extract_mesh(*download_map(), params, removed); });
}

TriangleMesh GpuReconstruction::mesh_on_device(const MeshParams& params,
                                               RemovedPieces* removed) const {
  const Impl& m = *impl_;
  const float join_m = m.map_params.voxel_size_m;
  // The blocks to mesh, planned on the host from their metadata (24 bytes a block).
  int32_t high_water_mark = 0;
  std::vector<BlockRef> allocated = allocated_blocks(&high_water_mark);
  const auto high_water = static_cast<std::size_t>(high_water_mark);
  const detail::MeshBlocks plan =
      detail::plan_mesh_blocks(std::move(allocated), high_water_mark, m.map_params, params.bounds);
  const auto n = static_cast<int32_t>(plan.blocks.size());
  if (n == 0) return detail::finish_mesh({}, params, join_m, removed);

  Buffer<BlockRef> d_blocks;
  Buffer<uint8_t> d_cells;
  Buffer<int32_t> d_index_of_ptr;
  Buffer<mc::McTable> table;
  d_blocks.assign(plan.blocks.data(), plan.blocks.size());
  d_cells.assign(plan.cells.data(), plan.cells.size());
  d_index_of_ptr.assign(plan.index_of_ptr.data(), high_water);
  table.assign(&mc::kMcTable, 1);
  kernels::MeshPassInput in = detail::mesh_pass_input(params, m.view.color != nullptr, plan);
  in.blocks = d_blocks.get();  // the device's copies
  in.index_of_ptr = d_index_of_ptr.get();
  in.cells = d_cells.get();
  in.table = table.get();

  // Pass one: each block's counts; the layout on the host. Each thread meshes its blocks one
  // after another in its own scratch (mesh_scratch_bytes(), ~27 KB): the more threads, the more
  // blocks at once (on an H200, the desk's 21 000 blocks in 84 ms on 32 768 threads, 294 ms on
  // 4096), as many as a quarter of the free device memory holds.
  constexpr int64_t kMostThreads = 32768;  // ~0.9 GB of scratch
  const auto fit = static_cast<int64_t>(free_device_memory() / 4 / mesh_scratch_bytes());
  const int threads =
      mesh_thread_count(n, static_cast<int>(std::clamp<int64_t>(fit, 1, kMostThreads)));
  Buffer<unsigned char> scratch;
  scratch.reset(static_cast<std::size_t>(threads) * mesh_scratch_bytes(), nullptr);
  Buffer<kernels::BlockMeshCount> d_counts;
  d_counts.reset(plan.blocks.size(), nullptr);
  count_meshes(m.view.read, in, scratch.get(), threads, d_counts.get());
  check_last("meshing (counting)");
  std::vector<kernels::BlockMeshCount> counts(plan.blocks.size());
  d_counts.download(counts.data(), counts.size());
  const detail::MeshLayout layout = detail::mesh_layout(counts.data(), n);
  const auto vertices = static_cast<std::size_t>(layout.vertices());
  const auto corners = static_cast<std::size_t>(layout.corners());
  Buffer<int64_t> vertex_offset, corner_offset;
  vertex_offset.assign(layout.vertex_offset.data(), layout.vertex_offset.size());
  corner_offset.assign(layout.corner_offset.data(), layout.corner_offset.size());
  in.counts = d_counts.get();
  in.vertex_offset = vertex_offset.get();
  in.corner_offset = corner_offset.get();

  // Pass two: the vertices and corners; pass three: the corners' vertex indices.
  Buffer<Vec3f> positions, normals;
  Buffer<Rgb8> colors;
  Buffer<uint8_t> levels;
  Buffer<uint16_t> edges;
  Buffer<kernels::EdgeRef> corner_refs;
  Buffer<int32_t> triangles;
  Buffer<unsigned long long> unresolved;
  positions.reset(vertices, nullptr);
  if (in.normals) normals.reset(vertices, nullptr);
  if (in.color) colors.reset(vertices, nullptr);
  levels.reset(vertices, nullptr);
  edges.reset(vertices, nullptr);
  corner_refs.reset(corners, nullptr);
  triangles.reset(corners, nullptr);
  unresolved.reset(1, nullptr);
  check_status(cudaMemset(unresolved.get(), 0, sizeof(unsigned long long)), "meshing");
  kernels::MeshArrays out;
  out.positions_w = positions.get();
  out.normals_w = normals.get();
  out.colors = colors.get();
  out.levels = levels.get();
  out.edges = edges.get();
  out.corners = corner_refs.get();
  write_meshes(m.view.read, in, scratch.get(), threads, out);
  check_last("meshing (writing)");
  resolve_corners(in, edges.get(), corner_refs.get(), static_cast<int64_t>(corners),
                  triangles.get(), unresolved.get());
  check_last("meshing (resolving corners)");

  TriangleMesh mesh;
  mesh.positions_w.resize(vertices);
  positions.download(mesh.positions_w.data(), vertices);
  if (in.normals) {
    mesh.normals_w.resize(vertices);
    normals.download(mesh.normals_w.data(), vertices);
  }
  if (in.color) {
    mesh.colors.resize(vertices);
    colors.download(mesh.colors.data(), vertices);
  }
  mesh.levels.resize(vertices);
  levels.download(mesh.levels.data(), vertices);
  mesh.triangles.resize(corners / 3);
  static_assert(sizeof(std::array<int32_t, 3>) == 3 * sizeof(int32_t));
  triangles.download(reinterpret_cast<int32_t*>(mesh.triangles.data()), corners);
  unsigned long long missing = 0;
  unresolved.download(&missing, 1);
  // As on the CPU: every corner's owner made its vertex; anything else is a bug, reported.
  if (missing != 0)
    fail(ErrorCode::InvalidData, "mesh: {} triangle corners found no vertex (internal error)",
         missing);
  detail::merge_boundary_vertices(counts.data(), layout, mesh);
  return detail::finish_mesh(std::move(mesh), params, join_m, removed);
}

std::vector<int64_t> GpuReconstruction::blocks_per_level() const {
  return impl_->level_blocks;
}

RaycastResult GpuReconstruction::download_model() const {
  const Impl& m = *impl_;
  const ImageLevel& m0 = m.model[0];
  return download_raycast(m0.camera, m.model_T_wc, m.view.color != nullptr,
                          {m0.depth.get(), m0.points.get(), m0.normals.get(), m.model_colors.get(),
                           m.model_levels.get()});
}

RaycastResult GpuReconstruction::render(const PinholeCamera& camera, const Pose& T_wc,
                                        const DepthRange& range) const {
  camera.validate("render camera");
  range.validate("render depth range");
  return on_device_else_host(
      "render", [&] { return impl_->render(camera, T_wc, range); },
      [&] {
        Raycaster raycaster(impl_->params.raycast);
        return RaycastResult(raycaster.raycast(*download_map(), camera, T_wc, range));
      });
}

namespace {

/// The GPU loop behind a Reconstruction (DeviceLoop).
class CudaLoop final : public DeviceLoop {
 public:
  CudaLoop(const ReconstructionParams& params, const CameraRig& rig, const VoxelBlockMap* map,
           const MapSession& session)
      : gpu_(map != nullptr ? std::make_unique<GpuReconstruction>(params, rig, *map, session)
                            : std::make_unique<GpuReconstruction>(params, rig)) {}

  FrameStats integrate(const RgbdFrame& frame, const Pose& T_wc) override {
    return gpu_->integrate(frame, T_wc);
  }
  FrameStats track_and_integrate(const RgbdFrame& frame, const Pose& T_wc_first, TrackResult* track,
                                 Pose* T_wc) override {
    const FrameStats s = gpu_->track_and_integrate(frame, T_wc_first);
    *track = gpu_->last_track();
    *T_wc = gpu_->trajectory().back().T_wc;
    return s;
  }
  std::vector<int64_t> blocks_per_level() const override { return gpu_->blocks_per_level(); }
  int64_t dropped_blocks() const override { return gpu_->dropped_blocks(); }
  int64_t map_memory_bytes() const override { return gpu_->map_memory_bytes(); }
  void download_map(VoxelBlockMap& map) const override { gpu_->download_map(map); }
  RaycastResult model() const override { return gpu_->download_model(); }
  std::vector<BlockRef> allocated_blocks() const override { return gpu_->allocated_blocks(); }
  RaycastResult render(const PinholeCamera& camera, const Pose& T_wc,
                       const DepthRange& range) const override {
    return gpu_->render(camera, T_wc, range);
  }
  TriangleMesh extract_mesh(const MeshParams& params, RemovedPieces* removed) const override {
    return gpu_->extract_mesh(params, removed);
  }

 private:
  std::unique_ptr<GpuReconstruction> gpu_;
};

}  // namespace

std::unique_ptr<Reconstruction> make_reconstruction(const ReconstructionParams& params,
                                                    const CameraRig& rig,
                                                    std::unique_ptr<VoxelBlockMap> map,
                                                    const MapSession& session) {
  auto loop = std::make_unique<CudaLoop>(params, rig, map.get(), session);
  return std::make_unique<Reconstruction>(params, rig, std::move(loop), std::move(map), session);
}

}  // namespace hivox::cuda

#pragma once
// The CUDA loop's launches: host-callable functions on the kernels' plain types (no CUDA types,
// no Eigen), defined in loop_kernels.cu. Every launch goes on the default stream (or into a
// LaunchGraph's recording); none waits for the device unless it says so.

#include <cstddef>
#include <cstdint>
#include <functional>

#include "fusion/fusion_kernels.h"
#include "hivox/core/camera.h"
#include "hivox/core/math.h"
#include "hivox/core/sensor_noise.h"
#include "hivox/map/map_view.h"
#include "hivox/map/voxel_block_map.h"
#include "mesh/mesh_passes.h"
#include "raycast/raycast_kernels.h"
#include "raycast/warp_kernels.h"
#include "refine/refine_kernels.h"
#include "track/gauss_newton.h"
#include "track/track_kernels.h"

namespace hivox::cuda {

/// Throws `Error(Cuda)` naming `what` when the last launch or call on the device failed.
void check_last(const char* what);

/// Counters of one frame's allocation, in device memory.
struct AllocCounters {
  int32_t missing = 0;       ///< distinct missing blocks recorded (may exceed the list)
  int32_t visible = 0;       ///< blocks in the visible list
  int32_t valid_pixels = 0;  ///< pixels with a valid depth
  int32_t inserted = 0;
  int32_t hash_full = 0;  ///< dropped: a level's excess entries ran out
  int32_t pool_full = 0;  ///< dropped: the pool ran out (or the missing list was full)
  int32_t raycast_hits = 0;
  int32_t icp_valid_pixels = 0;  ///< finest pyramid level: pixels with a normal
};

/// Block keys, each once: an open-addressing set of packed keys and the list of the distinct
/// keys (allocation's missing blocks, refinement's merge parents).
struct BlockKeySet {
  unsigned long long* keys = nullptr;  ///< `mask + 1` slots, all ones = empty
  uint32_t mask = 0;
  BlockKey* list = nullptr;  ///< the distinct keys, in no order
  int32_t capacity = 0;      ///< of `list`
};

/// Stage one of allocation: every valid pixel walks its truncation band through the levels;
/// blocks found are stamped with `frame` and listed as visible once, missing ones go into the
/// set. `missing.keys` must be cleared (all ones) before. `pixels_per_thread`: 1, 2 (2x1) or 4
/// (2x2) pixels walked by one thread, which skips the look-ups of blocks it has seen (the same
/// blocks found, fewer look-ups, fewer threads).
void find_blocks(const MapView& map, const kernels::DepthFrameView& depth, const Rigid3f& T_wc,
                 float mu_m, int32_t* stamps, int32_t frame, const BlockKeySet& missing,
                 BlockRef* visible, AllocCounters* counters, int pixels_per_thread = 1);

/// Stage two: inserts the `count` distinct missing blocks (lock-free, kernels::allocate_block)
/// and appends the new ones to the visible list, stamped; grows `bounds` (device memory) by
/// their super-blocks.
void insert_blocks(const MutableMapView& map, const BlockKeySet& missing, int32_t count,
                   BlockRef* visible, int32_t* stamps, int32_t frame, AllocCounters* counters,
                   kernels::SuperBlockBounds* bounds);

/// Integrates the frame into the visible blocks (the first `counters->visible` of at most
/// `max_blocks`): one thread per voxel, the block's surface summary and update count after.
void integrate(const MutableMapView& map, const BlockRef* blocks, int32_t max_blocks,
               const AllocCounters* counters, const kernels::DepthFrameView& depth,
               const kernels::ColorFrameView& color, const kernels::IntegrationConstants& k);

/// Registered colour packed as 32-bit words (kernels::pack_rgb).
void pack_color(const Rgb8* rgb, uint32_t* packed, int64_t n);

/// The raycast's hints (kernels::ray_hints), as the CPU's FrameHints gives them: the start hint,
/// the depth of a frame taken from the raycast's pose (`width` pixels a row) at pixel
/// (n x + n/2, n y + n/2) for ray (x, y) with n = `subsample`; the fallback, one depth per
/// raycast pixel (the previous raycast warped into this view). Either may be null: no hint.
struct RayHintImages {
  const float* depth_m = nullptr;
  int width = 0;
  int subsample = 1;
  const float* fallback_m = nullptr;
  /// The previous raycast's levels (the model's own image: each ray reads its pixel before it
  /// writes it): where each ray's search starts its look-ups (kernels::RayHints::level).
  const int8_t* levels = nullptr;
};

/// How the rays are launched (GpuReconstruction's set_split_marches, set_raycast_registers,
/// set_queued_marches).
struct RaycastLaunch {
  /// > 0: a warp where at most that many rays march splits each march across its lanes
  /// (kernels::split_march_from_hint).
  int split_at_most = 0;
  /// 0: at most 168 registers a thread (launch bounds: 12 warps a multiprocessor); else one of
  /// kRaycastRegisterCaps, more warps at once for some spilling.
  int registers_at_most = 0;
  /// Device memory for two counts and then `march_queue_pixels` pixel indices (null: none). Where
  /// the image has no more pixels than that, the rays are cast by two kernels: the first
  /// searches every ray at its hints and queues the rays whose search fails, the second takes
  /// each queued ray across a warp's 32 lanes (kernels::split_march_from_hint), the warps
  /// sharing the queue out. split_at_most and registers_at_most are then not used.
  int32_t* march_queue = nullptr;
  int64_t march_queue_pixels = 0;
};
/// The register caps the ray kernel is built with (besides none).
inline constexpr int kRaycastRegisterCaps[] = {128, 96, 80, 64};
/// The registers a thread of the ray kernel for `how` takes, as the device's driver reports
/// them (0 in the CPU emulation of CUDA).
int raycast_kernel_registers(const RaycastLaunch& how);

/// Raycasts the map over the depths [min_depth_m, max_depth_m] (no nearer than
/// kernels::nearest_ray_start, as the CPU's raycaster): range tiles from the blocks below
/// `high_water` (an upper bound will do),
/// with `k.occupancy`'s cells (when it has them, in device memory, covering every block) cleared
/// and marked on the way, then one ray per pixel; counts hits into `counters->raycast_hits`.
/// (Queuing the rays whose hints fail for a second pass that marched a ray a thread was slower:
/// a warp of marching rays diverges on every step, and one multiprocessor ran the longest warp
/// for the whole kernel. With `how.march_queue` the second pass takes a ray a warp instead.)
void raycast(const MapView& map, int32_t high_water, const PinholeCamera& camera,
             const Rigid3f& T_wc, float min_depth_m, float max_depth_m, kernels::RangeTiles tiles,
             const kernels::RayMarchConstants& k, const RayHintImages& hint,
             const kernels::RaycastOutputView& out, AllocCounters* counters,
             const RaycastLaunch& how = {});

/// warp_raycast_depth on the device: the raycast (`depth`, `points`, `normals`, `from_pixels`
/// each) seen from `view`, into `out` (one depth per pixel of the view); `nearest` is scratch of
/// one element per pixel.
void warp_depth(const kernels::WarpView& view, const float* depth, const Vec3f* points,
                const Vec3f* normals, int64_t from_pixels, uint32_t* nearest, float* out);

/// Depth preprocessing for tracking (the CPU's build_pyramid, per pixel): the bilateral filter
/// (radius 0: range check only), 2x2 downsampling within a surface, points and normals.
void filter_depth(const float* in, float* out, int width, int height, int radius,
                  float inv_2sigma_px2, float inv_2sigma_d2, float min_m, float max_m);
void downsample_depth(const float* in, float* out, int out_width, int out_height,
                      float max_jump_ratio);
/// Points and normals of a depth image; counts pixels with a normal into `valid` when not null.
void points_and_normals(const float* depth, const PinholeCamera& camera, float max_jump_ratio,
                        Vec3f* points, Vec3f* normals, int32_t* valid);
/// The model pyramid's next level: 2x2 averages of points, normals and depth within a surface.
void downsample_model(const Vec3f* points, const Vec3f* normals, const float* depth, int in_width,
                      Vec3f* out_points, Vec3f* out_normals, float* out_depth, int out_width,
                      int out_height, float max_jump_ratio);

/// One ICP pass over a pyramid level: the sums of the normal equations, in `sums` (device, 30
/// doubles: A's upper triangle row-major (21), b (6), r2, distance, inliers) and copied to
/// `host_sums` (the call waits for them). `partials` holds icp_partials_size(pixels) floats;
/// `done` is a counter of the passes' own, zero before the first pass (each pass leaves it zero).
int64_t icp_partials_size(int64_t pixels);
void icp_reduce(const kernels::IcpPass& pass, const Vec3f* points_c, const Vec3f* normals_c,
                int64_t pixels, const Vec3f* model_points, const Vec3f* model_normals,
                float* partials, unsigned* done, double* sums, double* host_sums);
/// One ICP pass with Gauss-Newton on the device: the pose comes from `state` (pass.T_wc is not
/// read), the model's from `T_model_cw` in device memory where it is not null (then a frame's
/// passes have the same arguments as every other frame's: LaunchGraph), else from
/// pass.T_model_cw; a pass at a level the state skips does nothing, and a one-thread kernel after
/// it steps the state with the sums (kernels::icp_update). Nothing waits: every pass is launched
/// one after another and the state is read back once.
void icp_pass_on_device(const kernels::IcpPass& pass, const Vec3f* points_c, const Vec3f* normals_c,
                        int64_t pixels, const Vec3f* model_points, const Vec3f* model_normals,
                        float* partials, unsigned* done, double* sums, kernels::IcpState* state,
                        const Rigid3f* T_model_cw, int level, double convergence_step);

/// Launches recorded once and replayed as one CUDA graph: one call from the host a replay, and
/// on the device the kernels follow each other without waiting for the host's launches.
/// `run(record)` makes the launches `record` makes: the first call one by one (which loads their
/// kernels: a kernel's first launch may load it, which a recording stream must not do), the
/// second records them and launches the graph, every later call launches the graph. The
/// launches keep the second call's arguments, so what changes between calls must be read from
/// device memory.
class LaunchGraph {
 public:
  LaunchGraph() = default;
  ~LaunchGraph();
  LaunchGraph(const LaunchGraph&) = delete;
  LaunchGraph& operator=(const LaunchGraph&) = delete;
  void run(const std::function<void()>& record, const char* what);

 private:
  bool launched_ = false;   // once, one by one
  void* stream_ = nullptr;  // CUDA's handles, kept out of this header
  void* graph_ = nullptr;
  void* exec_ = nullptr;
};

/// While it lives, the calling thread's launches go to `stream` (a cudaStream_t; null: the
/// default stream), and back to where they went before when it ends.
class LaunchesOn {
 public:
  explicit LaunchesOn(void* stream);
  ~LaunchesOn();
  LaunchesOn(const LaunchesOn&) = delete;
  LaunchesOn& operator=(const LaunchesOn&) = delete;

 private:
  void* previous_;
};

// ---- refinement (refine_kernels.cu): the CPU Refiner's decisions and the map's split and merge
// edits, per block on the device ----------------------------------------------------------------

/// What the decisions need, as plain data (RefineParams and the frame's pose).
struct RefineConstants {
  kernels::RefineLevels levels;
  bool det_cov = false;  ///< the DetCov criterion (else Detail)
  float mu_m = 0;
  int min_weight = 0, min_samples = 0, min_updates = 0;
  int unmeshable_cells = 0, unmeshable_min_weight = 0;
  SensorNoise noise;
  Rigid3f T_cw;  ///< the camera that just saw the blocks (their depth for the noise)
};

/// The candidates' lists: splits (visible blocks), the split parents of visible blocks (each
/// once, through `parents`), and the parents that may merge. `counts`: [0] splits, [1] parents,
/// [2] merges.
struct RefineLists {
  BlockRef* splits = nullptr;
  BlockKey* merges = nullptr;
  int32_t capacity = 0;  ///< of `splits` and `merges`
  BlockKeySet parents;
  int32_t* counts = nullptr;
};

/// Split candidates among the first `counters->visible` of `visible` (at most `max_visible`) and
/// their parents (the set `lists.parents` must be cleared before).
void split_candidates(const MapView& map, const BlockRef* visible, int32_t max_visible,
                      const AllocCounters* counters, const RefineConstants& k,
                      const RefineLists& lists);
/// Merge candidates among the first `lists.counts[1]` parents, a count the kernel reads:
/// `max_parents` (the grid) may be a bound the host knows without reading it back.
void merge_candidates(const MapView& map, int32_t max_parents, const RefineConstants& k,
                      const RefineLists& lists);

/// One merge: the parent's entry, its 8 children's entries and blocks, the parent's new block.
struct MergeJob {
  BlockKey parent;
  int32_t entry = kNoEntry;
  int32_t child_entry[8];
  int32_t child_block[8];
  int32_t block = kPtrEmpty;
  BlockSurface surface;
  int32_t ok = 0;
};
/// Looks the jobs' parents and children up; `ok` where the merge is still possible, counted into
/// `*ok_count` when given.
void merge_lookup(const MapView& map, MergeJob* jobs, int32_t n, int32_t* ok_count = nullptr);
/// Merges the jobs `ok` (the CPU's merge_blocks passes: fill the parents, publish them and empty
/// the children's entries, return the children's blocks and unlinked entries).
void merge_apply(const MutableMapView& map, MergeJob* jobs, int32_t n);

/// One split: the parent, the blocks its interpolation reads, its children's blocks and entries.
struct SplitJob {
  BlockRef parent;
  int32_t parents[8];
  int32_t neighbour_children[8][8];
  int32_t child_block[8];
  int32_t child_entry[8];
  BlockSurface child_surface[8];
  int32_t ok = 0;
};
/// `ok` where the parent is still the allocated block the job names, counted into `*ok_count`
/// when given.
void split_check(const MapView& map, SplitJob* jobs, int32_t n, int32_t* ok_count = nullptr);
/// Splits the jobs `ok` of [0, n), all parents of one level (the CPU's passes 1 to 3 for that
/// level).
void split_apply_level(const MutableMapView& map, SplitJob* jobs, int32_t n, float weight_scale);
/// Returns the split parents' blocks (of the jobs `ok`) to the pool and moves the level counts.
void split_finish(const MutableMapView& map, const SplitJob* jobs, int32_t n);

// ---- meshing (mesh_passes.cu): the passes of mesh/mesh_passes.h ------------------------------

/// Scratch bytes one meshing thread needs (its padded block).
std::size_t mesh_scratch_bytes();
/// Threads to mesh `blocks` blocks with: at most `most`, a whole number of thread blocks.
int mesh_thread_count(int64_t blocks, int most);
/// Pass one over the `in.block_count` blocks, by `threads` threads (mesh_thread_count), each with
/// its scratch in `scratch` (`threads` x mesh_scratch_bytes()): each block's counts.
void count_meshes(const MapView& map, const kernels::MeshPassInput& in, void* scratch, int threads,
                  kernels::BlockMeshCount* counts);
/// Pass two: each block's vertices and corners into `out` at its offsets (`in`'s counts and
/// offsets set).
void write_meshes(const MapView& map, const kernels::MeshPassInput& in, void* scratch, int threads,
                  const kernels::MeshArrays& out);
/// Pass three: the vertex index of each of the `n` corners; corners that find no vertex get 0
/// and are counted in `*unresolved`.
void resolve_corners(const kernels::MeshPassInput& in, const uint16_t* edges,
                     const kernels::EdgeRef* corners, int64_t n, int32_t* vertex_index,
                     unsigned long long* unresolved);

}  // namespace hivox::cuda

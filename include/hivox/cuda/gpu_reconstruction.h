#pragma once
/// @file
/// The online loop on a CUDA device: the map (hash tables, block pool, free lists) in device
/// memory, allocation, integration, raycasting and ICP tracking as CUDA kernels over the same
/// per-element functions as the CPU stages. Frames go in, poses and stats come out; the map and
/// the last raycast come back to the host only when asked for (meshing, saving, comparing).
/// Built with -DHIVOX_WITH_CUDA=ON (this header has no CUDA types).
///
/// Refinement (the CPU Refiner's decisions, split and merge), meshing (extract_mesh) and renders
/// (render) run on the device too; saving takes the map back to the host (download_map).

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "hivox/core/camera_rig.h"
#include "hivox/core/dataset.h"
#include "hivox/map/stored_map.h"
#include "hivox/map/voxel_block_map.h"
#include "hivox/mesh/extract_mesh.h"
#include "hivox/pipeline/reconstruction.h"
#include "hivox/raycast/raycaster.h"
#include "hivox/track/tracker.h"

namespace hivox::cuda {

/// The name of CUDA device `index`, or empty when there is none (no driver, no such device).
std::string device_name(int index = 0);
/// Throws `Error(Unsupported)` unless CUDA device `device` is here: one line naming it and the
/// devices there are (or none: no driver or no GPU).
void require_cuda_device(const Device& device);

/// The CUDA devices present, described (none without a driver or a GPU). Asking for each one's free
/// memory starts the runtime on it.
std::vector<DeviceInfo> cuda_devices();
/// CUDA device `index` described (as cuda_devices() does); nullopt when there is no such device.
std::optional<DeviceInfo> describe_cuda_device(int index);

class GpuReconstruction {
 public:
  /// A new, empty map. `params.device` must be a CUDA device that is present (else
  /// `Error(Unsupported)` naming it).
  GpuReconstruction(const ReconstructionParams& params, const CameraRig& rig);
  /// Continues `map` (copied to the device; its parameters replace `params.map`) as the CPU's
  /// Reconstruction continues a map: with `session.last_pose` (the camera's pose at the map's
  /// last frame) the first frame is tracked from it, and the refinement's cadence counts on from
  /// `session.frames_fused`.
  GpuReconstruction(const ReconstructionParams& params, const CameraRig& rig,
                    const VoxelBlockMap& map, const MapSession& session = {});
  ~GpuReconstruction();
  GpuReconstruction(const GpuReconstruction&) = delete;
  GpuReconstruction& operator=(const GpuReconstruction&) = delete;

  /// Fuses `frame` at the given pose (no tracking), then raycasts the model at it. Stage times
  /// are wall-clock on the host around each stage, the device synchronised at its end, except
  /// the allocation's, the integration's and the raycast's: the device's own (CUDA events), which
  /// need no wait. A frame returns without waiting for its raycast, so that the host copies the
  /// next frame in while the device raycasts; the next frame waits for it after its upload and
  /// reports it (its raycast_ms and raycast_hits are the raycast after the frame before).
  const FrameStats& integrate(const RgbdFrame& frame, const Pose& T_wc);
  /// Tracks `frame` against the last model (the first frame of a new map takes `T_wc_first`),
  /// fuses it unless tracking is lost, and raycasts the model at the new pose.
  const FrameStats& track_and_integrate(const RgbdFrame& frame,
                                        const Pose& T_wc_first = Pose::Identity());

  /// Waits until the device has done all it was given: the last frame's raycast, which the
  /// frame did not wait for. For timing a loop by the host's clock; results read from the device
  /// (the model, the map, a mesh) wait for it themselves.
  void synchronize() const;
  /// Where tracking's Gauss-Newton steps run: on the device (the default), in each pass's last
  /// block, every pass launched at once and the result read back once per frame; or on the
  /// host, each pass's sums read back before the next pass. Both take the same steps
  /// (track/gauss_newton.h); the device's way saves a round trip a pass (on an H200, tracking
  /// 0.48 instead of 0.54 ms a frame on fr1/rpy).
  void set_gauss_newton_on_device(bool on);

  /// Whether tracking's ICP passes (with Gauss-Newton on the device: two kernels a pass, 40 a
  /// frame with the default iterations) are launched as one CUDA graph, recorded at the second
  /// tracked frame (the first launches them one by one), instead of one launch at a time: one call
  /// from the host instead of 40, and no wait for the host's launches between the kernels. The same
  /// kernels with the same arguments (the poses are read from device memory), so the same poses.
  /// Off by default: not yet timed on a GPU.
  void set_tracking_graph(bool on);
  /// Whether a frame goes up to the device, and its tracking pyramid is made there (bilateral
  /// filter, downsampling, points and normals), on a stream of its own beside the raycast the
  /// frame before ends with, instead of after it: the host copies the frame, queues it and
  /// launches the pyramid before it waits for that raycast, and the device does them while it
  /// raycasts. The frames' depth then takes two device images in turn (the raycast starts its
  /// rays at its own frame's depth), 1.2 MB more at 640x480. Scheduling only: the same poses and
  /// map. Off by default: not yet timed on a GPU.
  void set_upload_beside_raycast(bool on);
  /// With ReconstructionParams::refine_after_raycast: whether the refinement goes on a stream of
  /// its own beside the model raycast (the default), its look-ups overlapping the raycast and its
  /// writes waiting on the device for the raycast's end, or after the raycast on the loop's
  /// stream, one after the other. The same splits and merges in the same order on the same map:
  /// only the device's schedule differs. For timing what the overlap saves, and for telling a
  /// fault that needs the overlap from one that needs the order.
  void set_refine_beside_raycast(bool on);
  /// How the model raycast marches the rays whose hints fail: `at_most` 0 (the default), each in
  /// its own thread; > 0, a warp where at most that many rays march splits each of their marches
  /// across its 32 lanes, one ray after another (kernels::split_march_from_hint), instead of
  /// waiting for its longest: a warp's wait on its look-ups shrinks to its longest stretch's. Up
  /// to 1 gained nothing on an H200 (2026-11-27): the slowest warps hold many marching rays
  /// (bench/ray_cost); 8 and 32 are not yet timed, so not the default.
  void set_split_marches(int at_most);
  /// Whether the model raycast takes two kernels: the first searches every ray at its hints and
  /// queues the rays whose search fails, the second takes each queued ray across a warp's 32
  /// lanes (kernels::split_march_from_hint), its warps taking the next ray as they finish one.
  /// Where a warp's rays march, the one kernel waits for the longest (split_marches takes them
  /// one after another); here the marches (about 6 % of fr1/rpy's rays, in 20 % of the warps)
  /// go to as many warps as there are, and the searches' kernel, without the march's code,
  /// ends with its slowest search (bench/ray_cost models both). The hits are split marches'
  /// (set_split_marches(32) gives the same model): a lane's stretch samples its ray at other
  /// depths than a whole march, so hits move by a fraction of a voxel. A queue of the model's
  /// pixels (300 KB at 320x240). Not yet timed on a GPU, so not the default; set_split_marches
  /// and set_raycast_registers do not apply while it is on. Renders (render) march every ray
  /// whole in one kernel, whatever this and set_split_marches say.
  void set_queued_marches(bool on);

  /// At most how many registers a thread of the model raycast's kernel takes: 0 (the default),
  /// as many as the compiler likes (160 for sm_90 with CUDA 13, so 12 warps of it fit a
  /// multiprocessor: the 2400 warps of a 320x240 model take two waves); 128, 96, 80 or 64: more
  /// warps at once (16, 20, 24, 32), the rest of a thread's values spilled to its local memory
  /// (a few dozen bytes loaded a ray). The same rays, the same arithmetic: the same model. 128
  /// was 4 % slower on an H200 (2026-11-26); the others, which fit every warp at once, are not
  /// yet timed, so not the default. `Error(InvalidArgument)` for other counts.
  void set_raycast_registers(int at_most);
  /// How many pixels' truncation bands one thread of the allocation walks: 1 (the default), 2
  /// (2x1) or 4 (2x2), the thread skipping the look-ups of blocks it has seen (16 remembered). The
  /// same blocks found: neighbouring pixels' bands cross the same blocks, so the hash-table
  /// look-ups a pixel fall (fr1/rpy frame 119, `bench/ray_cost`: 8.60, 6.08, 4.77 with 3 levels;
  /// 5.98, 3.78, 2.60 on the fixed grid) while the threads are fewer. Not yet timed on a GPU, so
  /// not the default. `Error(InvalidArgument)` for other counts.
  void set_allocation_pixels(int per_thread);
  /// The registers a thread of the model raycast's kernel takes now, as the device's driver
  /// reports them (0 in the CPU emulation of CUDA).
  int raycast_registers() const;

  const std::vector<StampedPose>& trajectory() const;
  const std::vector<FrameStats>& frames() const;
  /// The last frame's tracking (Good, with no ICP numbers, for a frame fused at a given pose).
  const TrackResult& last_track() const;
  const MapParams& map_params() const;

  /// The allocated blocks (all levels, in pool order) from the device's block metadata (24 bytes
  /// a block cross the bus, not the voxels); `*high_water` (when not null) receives the pool's
  /// high-water mark.
  std::vector<BlockRef> allocated_blocks(int32_t* high_water = nullptr) const;
  /// A host copy of the device map (same parameters, same tables and pool indices).
  std::unique_ptr<VoxelBlockMap> download_map() const;
  /// Copies the device map into `map`, a host map of the same parameters (map_params()).
  void download_map(VoxelBlockMap& map) const;
  /// The device map's mesh, as hivox::extract_mesh gives it for the downloaded map: marching
  /// cubes in passes on the device (count, write, resolve the corners; mesh/mesh_passes.h), the
  /// vertices that several blocks make on level boundaries merged on the host, then the same
  /// cropping and small-piece removal. Only the block list (24 bytes a block) and the mesh cross
  /// the bus. Where the device has no memory left for the passes, the map is meshed on the host
  /// (the same mesh), with a warning.
  TriangleMesh extract_mesh(const MeshParams& params = {}, RemovedPieces* removed = nullptr) const;
  /// Allocated blocks per level (finest first), from the device's counters as the last frame
  /// read them (no round trip).
  std::vector<int64_t> blocks_per_level() const;
  /// The last model raycast (the depth camera subsampled by the tracking's model_subsample),
  /// copied to the host.
  RaycastResult download_model() const;
  /// The model seen through `camera` from `T_wc` over the depths of `range`, raycast on the
  /// device as the CPU's Raycaster casts it without hints (every ray marches its range tile,
  /// the same shared march): only the images cross the bus, not the map. The frame's raycast is
  /// left as it is. Where the device has no memory left for the images, the map is raycast on the
  /// host (the same render), with a warning. `Error(InvalidArgument)` for a bad camera or range.
  RaycastResult render(const PinholeCamera& camera, const Pose& T_wc,
                       const DepthRange& range) const;
  /// Blocks allocated on the device (all levels).
  int64_t blocks_in_use() const;
  /// Blocks dropped so far because a capacity ran out (the continued map's included).
  int64_t dropped_blocks() const;
  /// Device memory held by the map, and by the whole loop (map, frame and pyramid buffers). The
  /// hash tables and free lists are held whole; the pool's voxels and metadata are committed as
  /// its blocks need them, in the driver's granularity (2 MiB). Where the device's memory runs
  /// out, the pool stops growing (192 MiB left free): new blocks beyond it are dropped and counted,
  /// splits and merges wait, with a warning.
  int64_t map_memory_bytes() const;
  int64_t device_memory_bytes() const;

 private:
  TriangleMesh mesh_on_device(const MeshParams& params, RemovedPieces* removed) const;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// A Reconstruction whose frames run on the CUDA device `params.device` (a GpuReconstruction
/// behind it): the CLI's and the Python module's runs with `--device cuda[:N]`. Its map() is the
/// host's copy, refreshed when read after the device fused. With `map` it continues that map
/// (tracking from `session.last_pose`).
std::unique_ptr<Reconstruction> make_reconstruction(const ReconstructionParams& params,
                                                    const CameraRig& rig,
                                                    std::unique_ptr<VoxelBlockMap> map = nullptr,
                                                    const MapSession& session = {});

}  // namespace hivox::cuda

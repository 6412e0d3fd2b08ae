#pragma once
/// @file
/// The reconstruction façade: per frame, allocate -> integrate -> (refine) -> raycast, with
/// per-stage timings and block counts. The stages stay callable on their own (fusion, raycast
/// modules) for tests and benchmarks.

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "hivox/core/camera.h"
#include "hivox/core/camera_rig.h"
#include "hivox/core/dataset.h"
#include "hivox/core/device.h"
#include "hivox/core/pose.h"
#include "hivox/core/timer.h"
#include "hivox/fusion/integrator.h"
#include "hivox/map/stored_map.h"
#include "hivox/map/voxel_block_map.h"
#include "hivox/pipeline/device_loop.h"
#include "hivox/raycast/raycaster.h"
#include "hivox/refine/refiner.h"
#include "hivox/track/tracker.h"

namespace hivox {

/// Every setting of a reconstruction, each in one place: the truncation band is the map's
/// (`map.truncation_m`) and the depth range the fusion's (`fusion.depth_range`); refinement,
/// raycasting and tracking read them from there.
struct ReconstructionParams {
  /// Where the map lives and every stage runs: the CPU, or a CUDA device through
  /// hivox::cuda::make_reconstruction (builds with -DHIVOX_WITH_CUDA=ON; docs/cuda.md).
  Device device;
  MapParams map;
  FusionParams fusion;
  RefineParams refine;  ///< used when map.levels > 1
  RaycastParams raycast;
  TrackParams track;  ///< used by track_and_integrate
  /// Raycast the model from each frame's pose after integrating it (tracking needs it; with
  /// given poses it only feeds renders and can be switched off for speed).
  bool raycast_every_frame = true;
  /// The per-frame raycast starts each ray at the depth just fused; where the frame has no
  /// depth, at the depth of the previous frame's raycast warped into this view (such rays
  /// otherwise search their whole depth range). false: those rays search the whole range.
  bool previous_raycast_hints = true;
  /// Refine the hierarchy after the frame's model raycast instead of before it: the model the
  /// next frame tracks against is then the map before this frame's splits and merges (they
  /// show in the next raycast). On a device the refinement, whose decisions wait for the host,
  /// then runs while the raycast does instead of before it. Not yet on a GPU: there a run on
  /// real data failed with an illegal memory access in the raycast (docs/cuda.md).
  bool refine_after_raycast = false;

  /// Validates every part (a device other than the CPU is checked where the loop is made).
  void validate() const;
  /// The settings in words; `rig` (optional): the sensor, whose noise model the refinement uses
  /// unless `refine.noise` is set.
  std::string to_string(const CameraRig* rig = nullptr) const;
};

/// What happened to one frame. Times are wall-clock milliseconds.
struct FrameStats {
  std::size_t index = 0;
  double timestamp_s = 0;
  double read_ms = 0;    ///< decoding the frame (measured by the caller)
  double upload_ms = 0;  ///< copying the frame to the device (0 on the CPU)
  double track_ms = 0;
  double allocate_ms = 0;
  double integrate_ms = 0;
  double refine_ms = 0;
  /// The model raycast after this frame's fusion; on a device (`GpuReconstruction`), the one
  /// this frame waited for: the raycast after the frame before, which the frame's tracking uses
  /// (a device frame does not wait for the raycast it ends with), its time the device's own.
  double raycast_ms = 0;
  double total_ms = 0;  ///< processing, reading excluded
  int64_t valid_pixels = 0;
  int64_t visible_blocks = 0;
  int64_t new_blocks = 0;
  int64_t dropped_blocks = 0;
  int64_t blocks_total = 0;
  std::vector<int64_t> blocks_per_level;  ///< finest first
  int64_t splits = 0;
  int64_t merges = 0;
  int64_t refine_waiting = 0;        ///< splits/merges postponed for lack of room
  int64_t raycast_hits = 0;          ///< of the raycast of raycast_ms
  int64_t raycast_hits_at_hint = 0;  ///< of them, found near their start hint (no march)
  /// Tracking (frames from track_and_integrate; others are Good with no ICP numbers).
  TrackingQuality tracking = TrackingQuality::Good;
  bool fused = true;  ///< false for a lost frame: not integrated, previous pose kept
  double track_inlier_ratio = 0;
  double track_rms_m = 0;
  double track_condition = 0;
  int track_iterations = 0;

  /// Takes in the tracking's verdict and numbers.
  void take_track(const TrackResult& t);
};

/// Mean milliseconds per frame of each stage over a run (zeros for no frame).
struct StageTimes {
  double read_ms = 0, upload_ms = 0, track_ms = 0, allocate_ms = 0, integrate_ms = 0, refine_ms = 0,
         raycast_ms = 0, total_ms = 0;
  /// Frames per second of processing (reading excluded); 0 for no frame.
  double fps() const { return total_ms > 0 ? 1000.0 / total_ms : 0.0; }
};
StageTimes mean_stage_times(std::span<const FrameStats> frames);

/// Frames by tracking verdict (frames fused with given poses count as good).
struct TrackingCounts {
  int64_t good = 0, poor = 0, lost = 0;
};

/// Consecutive frames whose tracking was not good. Poor frames are fused (only lost ones are
/// not), so a long stretch of them can leave the model, and every pose tracked against it
/// after, offset without a single frame being lost.
struct PoorTrackingStretch {
  std::size_t first_index = 0, last_index = 0;  ///< the frames' indices in their dataset
  int64_t poor = 0;                             ///< frames fused with poor tracking
  int64_t lost = 0;                             ///< frames lost among them (not fused)
  /// Of the poor frames: those with too few inliers (`TrackParams::poor_inlier_ratio`), and
  /// the others, whose geometry left a direction of motion unconstrained (`poor_condition`).
  int64_t few_inliers = 0, unconstrained = 0;
  double min_inlier_ratio = 1, max_inlier_ratio = 0;  ///< over the `few_inliers` frames
};
/// The stretches of `frames` (in the order run) with at least `min_poor` poor frames, a
/// stretch ending at a good frame; `track` gives the thresholds the verdicts came from.
std::vector<PoorTrackingStretch> poor_tracking_stretches(std::span<const FrameStats> frames,
                                                         const TrackParams& track,
                                                         int64_t min_poor);

class Reconstruction {
 public:
  /// `rig`: the sensor whose frames are fused (cameras, their relative pose, depth noise).
  Reconstruction(const ReconstructionParams& params, const CameraRig& rig);
  /// Continues into `map` (e.g. loaded from a map file), which `session` describes. The map's
  /// shape (voxel size, levels, truncation, colour) must equal `params.map`'s, else
  /// `Error(InvalidArgument)` names the first field that differs; its capacities are its own.
  /// Frames fused from here on continue the refinement's cadence; in track_and_integrate the
  /// first frame is tracked against the map (not fused blindly at its start pose).
  Reconstruction(const ReconstructionParams& params, const CameraRig& rig,
                 std::unique_ptr<VoxelBlockMap> map, const MapSession& session);
  /// Frames run on `loop` (another device; see DeviceLoop); `map` (null for a new map) is the
  /// map the loop continues, kept on the host as the copy that map() refreshes when read.
  Reconstruction(const ReconstructionParams& params, const CameraRig& rig,
                 std::unique_ptr<DeviceLoop> loop, std::unique_ptr<VoxelBlockMap> map,
                 const MapSession& session);
  ~Reconstruction();

  const ReconstructionParams& params() const { return params_; }
  const CameraRig& rig() const { return rig_; }
  /// The settings in words, with the sensor's noise model where the refinement uses it.
  std::string describe() const { return params_.to_string(&rig_); }

  /// Fuses `frame` at camera-to-world pose `T_wc`. `read_ms` is recorded in the statistics.
  const FrameStats& integrate(const RgbdFrame& frame, const Pose& T_wc, double read_ms = 0.0);

  /// The online loop: estimates the pose of `frame` by ICP against the raycast of the model
  /// from the previous pose, then fuses it there (allocate, integrate, refine, raycast). The
  /// first frame is fused at `T_wc_first`; in a reconstruction that continues a map it is tracked
  /// from `T_wc_first` instead. A frame whose tracking is lost is not fused and keeps the previous
  /// pose (the motion prior restarts).
  const FrameStats& track_and_integrate(const RgbdFrame& frame, double read_ms = 0.0,
                                        const Pose& T_wc_first = Pose::Identity());
  /// Throws `Error(InvalidArgument)` when this reconstruction cannot track its rig's frames
  /// (images too small for the ICP pyramid); track_and_integrate would fail on its second frame.
  void check_tracking() const { tracker_.check_sizes(rig_.depth_camera, model_camera()); }
  /// Outcome of the last tracked frame's ICP.
  const TrackResult& last_track() const { return last_track_; }
  const TrackingCounts& tracking_counts() const { return tracking_counts_; }

  /// The map (on another device: the host's copy, refreshed when the device has fused since).
  const VoxelBlockMap& map() const;
  VoxelBlockMap& map();
  /// The raycast of the last frame (empty before the first, or without raycast_every_frame), at
  /// the tracking model's resolution (`track.model_subsample`); `render` gives full renders.
  const RaycastResult& last_raycast() const;
  /// The map's mesh (hivox::extract_mesh); on another device, made there, without copying the
  /// map to the host.
  TriangleMesh extract_mesh(const MeshParams& params = {}, RemovedPieces* removed = nullptr) const;
  /// Raycasts the model from any pose with any camera (renders, overviews), out to
  /// `max_depth_m` (0: the fusion's depth range). On another device, cast there: only the images
  /// come back, not the map.
  RaycastResult render(const PinholeCamera& camera, const Pose& T_wc,
                       float max_depth_m = 0.0f) const;

  /// A viewpoint that shows the whole model: behind and above the trajectory (along the cameras'
  /// mean viewing direction and image "up"), looking at the centre of the allocated blocks, far
  /// enough back for `camera` to see them all. `max_depth_m` receives the depth to render to.
  Pose overview_pose(const PinholeCamera& camera, float* max_depth_m) const;

  const std::vector<FrameStats>& frame_stats() const { return frames_; }
  const std::vector<StampedPose>& trajectory() const { return trajectory_; }
  int64_t peak_blocks() const { return peak_blocks_; }
  /// Allocated blocks, all levels and per level (finest first); blocks dropped so far because a
  /// capacity ran out; the map's memory in bytes. Cheap on every device: the host's copy of a
  /// device map is not refreshed for them.
  int64_t blocks_in_use() const;
  std::vector<int64_t> blocks_per_level() const;
  int64_t dropped_blocks() const;
  int64_t map_memory_bytes() const;
  /// Where the reconstruction stands, the map's earlier frames included: what a map file keeps
  /// beside the voxels to continue it.
  MapSession session() const;

 private:
  ReconstructionParams params_;
  CameraRig rig_;
  std::unique_ptr<VoxelBlockMap> map_;
  TsdfIntegrator integrator_;
  Refiner refiner_;
  Raycaster raycaster_;
  /// Allocate, integrate, refine and raycast `frame` at `T_wc`, filling the stage statistics.
  void fuse(const RgbdFrame& frame, const Pose& T_wc, FrameStats& s);
  /// Completes `s` (frame, block counts, total time since `total` started), appends it and the
  /// pose to the history.
  const FrameStats& record(const RgbdFrame& frame, const Pose& T_wc, const Stopwatch& total,
                           FrameStats& s);
  /// The camera of the per-frame raycast (the depth camera, subsampled for tracking).
  PinholeCamera model_camera() const;
  FrameHints hints_;  ///< builds the per-frame raycast's hints

  Tracker tracker_;
  TrackResult last_track_;
  MotionPrior motion_{params_.track.constant_velocity};
  TrackingCounts tracking_counts_;
  std::vector<FrameStats> frames_;
  std::vector<StampedPose> trajectory_;
  int64_t peak_blocks_ = 0;
  MapSession resumed_;  ///< the session of the map this reconstruction continues
  bool continues_map_ = false;
  std::unique_ptr<DeviceLoop> loop_;  ///< frames run there when set
  mutable bool map_stale_ = false;    ///< the device fused since map_ was refreshed
  mutable RaycastResult device_model_;
  mutable bool model_stale_ = false;
  Reconstruction(const ReconstructionParams& params, const CameraRig& rig,
                 std::unique_ptr<VoxelBlockMap> map, const MapSession& session, bool continues_map,
                 std::unique_ptr<DeviceLoop> loop);
};

}  // namespace hivox

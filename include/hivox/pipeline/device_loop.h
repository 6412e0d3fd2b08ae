#pragma once
/// @file
/// The per-frame loop on another device than the CPU, behind a Reconstruction: frames go in,
/// stats come out, renders and meshes are made there, and the map and the model raycast come
/// back to the host when read. The CUDA loop implements it (hivox::cuda::make_reconstruction, in
/// builds with -DHIVOX_WITH_CUDA=ON).

#include <cstdint>
#include <vector>

#include "hivox/core/dataset.h"
#include "hivox/core/pose.h"
#include "hivox/map/voxel_block_map.h"
#include "hivox/mesh/extract_mesh.h"
#include "hivox/raycast/raycaster.h"
#include "hivox/track/tracker.h"

namespace hivox {

struct FrameStats;  // reconstruction.h

class DeviceLoop {
 public:
  virtual ~DeviceLoop() = default;
  /// Fuses `frame` at `T_wc` (refines, raycasts the model); its stage statistics.
  virtual FrameStats integrate(const RgbdFrame& frame, const Pose& T_wc) = 0;
  /// Tracks `frame` against the last model (the first frame of a new map is fused at
  /// `T_wc_first`) and fuses it unless tracking is lost; its stage statistics, the tracking in
  /// `*track` and the pose the frame keeps (the previous one when lost) in `*T_wc`.
  virtual FrameStats track_and_integrate(const RgbdFrame& frame, const Pose& T_wc_first,
                                         TrackResult* track, Pose* T_wc) = 0;
  /// Allocated blocks per level (finest first), without copying the map.
  virtual std::vector<int64_t> blocks_per_level() const = 0;
  /// Blocks dropped so far because a capacity ran out (the continued map's included).
  virtual int64_t dropped_blocks() const = 0;
  /// Device memory the map holds, in bytes.
  virtual int64_t map_memory_bytes() const = 0;
  /// The allocated blocks (all levels), without copying the voxels.
  virtual std::vector<BlockRef> allocated_blocks() const = 0;
  /// Copies the device's map into `map` (a map of the same parameters on the host).
  virtual void download_map(VoxelBlockMap& map) const = 0;
  /// The last model raycast, copied to the host.
  virtual RaycastResult model() const = 0;
  /// The model seen through `camera` from `T_wc` over `range`, raycast there as the CPU's
  /// Raycaster casts it without hints; only the images come back.
  virtual RaycastResult render(const PinholeCamera& camera, const Pose& T_wc,
                               const DepthRange& range) const = 0;
  /// The map's mesh, made on the device: what hivox::extract_mesh gives for the downloaded map.
  virtual TriangleMesh extract_mesh(const MeshParams& params, RemovedPieces* removed) const = 0;
};

}  // namespace hivox

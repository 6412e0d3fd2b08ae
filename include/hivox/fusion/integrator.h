#pragma once
/// @file
/// Depth fusion into the voxel block map (DESIGN §3): two-stage allocation of the blocks crossed
/// by each pixel's truncation band, then the TSDF/colour update of those blocks.

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "hivox/core/camera_rig.h"
#include "hivox/core/dataset.h"
#include "hivox/core/image.h"
#include "hivox/core/pose.h"
#include "hivox/fusion/params.h"
#include "hivox/map/voxel_block_map.h"

namespace hivox {

/// One RGB-D frame with its sensor and pose, as fusion consumes it.
struct FusionInput {
  const DepthImage* depth_m = nullptr;  ///< required; metres, 0 = invalid
  const ColorImage* color = nullptr;    ///< optional
  /// The depth camera, and the colour camera and its pose when `color` is set.
  CameraRig rig;
  Pose T_wc = Pose::Identity();  ///< depth camera to world
};

/// The fusion input of `frame` recorded by `rig`, seen from pose `T_wc`: its depth, and its
/// colour when it has any. `frame` must outlive it.
FusionInput fusion_input(const CameraRig& rig, const RgbdFrame& frame, const Pose& T_wc);

struct AllocationStats {
  int64_t valid_pixels = 0;    ///< pixels with depth inside the depth range
  int64_t new_blocks = 0;      ///< blocks newly allocated this frame
  int64_t dropped_blocks = 0;  ///< blocks that could not be allocated (capacity)
};

/// What allocation hands on to integration and refinement: the blocks a frame's truncation band
/// touches (all levels, each once; new ones included), and what happened.
struct Allocation {
  std::vector<BlockRef> visible_blocks;
  AllocationStats stats;
};

class TsdfIntegrator {
 public:
  explicit TsdfIntegrator(const FusionParams& params = {});
  ~TsdfIntegrator();
  TsdfIntegrator(TsdfIntegrator&&) noexcept;
  TsdfIntegrator& operator=(TsdfIntegrator&&) noexcept;

  const FusionParams& params() const { return params_; }

  /// Stage 1 marks the blocks every valid pixel's band [d - mu, d + mu] crosses (walking from
  /// the coarsest level down through split blocks); stage 2 inserts the missing ones. Returns
  /// the blocks the band touches. The result is independent of the thread count (the order of
  /// the blocks is not).
  Allocation allocate(VoxelBlockMap& map, const FusionInput& input);

  /// Updates every voxel of `blocks` (allocated blocks of `map`, typically `allocate`'s) with
  /// the frame.
  void integrate(VoxelBlockMap& map, const FusionInput& input, std::span<const BlockRef> blocks);

  /// `allocate` then `integrate` of the visible blocks.
  Allocation fuse(VoxelBlockMap& map, const FusionInput& input);

 private:
  struct Scratch;
  /// The CPU's allocation: per-thread look-up caches and lists of missing blocks, merged.
  Allocation allocate_cpu(VoxelBlockMap& map, const FusionInput& input);
  FusionParams params_;
  std::unique_ptr<Scratch> scratch_;
};

/// Checks a fusion input: depth present, cameras valid, image sizes match the cameras.
/// Throws `Error(InvalidArgument)` naming the mismatch.
void validate_input(const FusionInput& input);

}  // namespace hivox

#pragma once
/// @file
/// Depth fusion into the voxel block map (DESIGN §3): two-stage allocation of the blocks crossed
/// by each pixel's truncation band, then the TSDF/colour update of those blocks.

#include <cstdint>
#include <memory>
#include <vector>

#include "hivox/core/camera.h"
#include "hivox/core/dataset.h"
#include "hivox/core/image.h"
#include "hivox/core/pose.h"
#include "hivox/fusion/params.h"
#include "hivox/map/voxel_block_map.h"

namespace hivox {

/// One RGB-D frame with its calibration and pose, as fusion consumes it.
struct FusionInput {
  const DepthImage* depth_m = nullptr;  ///< required; metres, 0 = invalid
  PinholeCamera depth_camera;
  const ColorImage* color = nullptr;      ///< optional
  PinholeCamera color_camera;             ///< used when `color` is set
  Pose T_color_depth = Pose::Identity();  ///< depth-camera point -> colour-camera point
  Pose T_wc = Pose::Identity();           ///< depth camera to world
};

/// The fusion input of `frame` of a dataset described by `info`, seen from pose `T_wc`: its
/// depth, and its colour when it has any, with the dataset's cameras. `frame` must outlive it.
FusionInput fusion_input(const DatasetInfo& info, const RgbdFrame& frame, const Pose& T_wc);

struct AllocationStats {
  int64_t valid_pixels = 0;    ///< pixels with depth inside the depth range
  int64_t visible_blocks = 0;  ///< blocks touched by the truncation band (all levels)
  int64_t new_blocks = 0;      ///< of which newly allocated this frame
  int64_t dropped_blocks = 0;  ///< blocks that could not be allocated (capacity)
};

class TsdfIntegrator {
 public:
  explicit TsdfIntegrator(const FusionParams& params = {});
  ~TsdfIntegrator();
  TsdfIntegrator(TsdfIntegrator&&) noexcept;
  TsdfIntegrator& operator=(TsdfIntegrator&&) noexcept;

  const FusionParams& params() const { return params_; }

  /// Stage 1 marks the blocks every valid pixel's band [d - mu, d + mu] crosses (walking from
  /// the coarsest level down through split blocks); stage 2 inserts the missing ones. The
  /// result is independent of the thread count. Also collects the visible blocks.
  AllocationStats allocate(VoxelBlockMap& map, const FusionInput& input);

  /// Updates every voxel of the visible blocks (from the last `allocate`).
  void integrate(VoxelBlockMap& map, const FusionInput& input);

  /// `allocate` then `integrate`.
  AllocationStats fuse(VoxelBlockMap& map, const FusionInput& input);

  /// Blocks touched by the last `allocate` (all levels, each once).
  const std::vector<BlockRef>& visible_blocks() const { return visible_; }

 private:
  struct Scratch;
  FusionParams params_;
  std::vector<BlockRef> visible_;
  std::unique_ptr<Scratch> scratch_;
};

/// Checks a fusion input: depth present, camera valid, image sizes match the cameras.
/// Throws `Error(InvalidArgument)` naming the mismatch.
void validate_input(const FusionInput& input);

}  // namespace hivox

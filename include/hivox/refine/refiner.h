#pragma once
/// @file
/// Where blocks move between levels (DESIGN §4): to a finer level where the surface is complex,
/// back where it is simple. The refiner judges blocks by their complexity and asks the map to
/// split or merge them (hivox/map/hierarchy_edit.h); the result does not depend on the thread
/// count.

#include <cstdint>
#include <span>
#include <vector>

#include "hivox/core/pose.h"
#include "hivox/map/voxel_block_map.h"
#include "hivox/refine/params.h"

namespace hivox {

struct RefineStats {
  int64_t evaluated = 0;  ///< blocks whose complexity was computed
  int64_t splits = 0;
  int64_t merges = 0;
  int64_t waiting = 0;  ///< splits or merges postponed for lack of room
};

class Refiner {
 public:
  /// `sensor_noise`: the depth noise of the sensor whose frames are fused (CameraRig::
  /// depth_noise), used unless `params.noise` is set.
  explicit Refiner(const RefineParams& params = {},
                   const SensorNoise& sensor_noise = SensorNoise::kinect());
  const RefineParams& params() const { return params_; }
  /// The noise model the thresholds use: `params().noise`, else the sensor's.
  const SensorNoise& noise() const { return noise_; }

  /// One pass (every `every_n_frames`-th call): judges `candidates` (typically the blocks the
  /// last frame touched) for splitting and their parents for merging, then asks the map to merge
  /// and split them. `T_wc` is the camera that just observed them: its depth sets the
  /// noise-aware thresholds.
  RefineStats refine(VoxelBlockMap& map, std::span<const BlockRef> candidates,
                     const Pose& T_wc = Pose::Identity());

  /// Complexity of pool block `ptr` under the configured criterion (-1: too little observed
  /// surface to judge).
  float complexity(const VoxelBlockMap& map, int32_t ptr, float* mean_weight = nullptr) const;

  /// Continues a cadence begun elsewhere (a map saved after `calls` frames and loaded again), so
  /// that the next passes fall on the same frames as without the interruption.
  void resume_after(int64_t calls) { calls_ = calls; }

 private:
  /// The CPU's pass: criteria in parallel over the candidates, then the map's edits.
  RefineStats refine_cpu(VoxelBlockMap& map, std::span<const BlockRef> candidates,
                         const Pose& T_wc);
  RefineParams params_;
  SensorNoise noise_;
  int64_t calls_ = 0;
};

}  // namespace hivox

#pragma once
/// @file
/// Split and merge between frames (DESIGN §4): blocks move to a finer level where the surface is
/// complex and back where it is simple. All passes are parallel, lock-free and give the same
/// map whatever the thread count.

#include <cstdint>
#include <span>
#include <vector>

#include "hivox/core/pose.h"
#include "hivox/map/voxel_block_map.h"
#include "hivox/refine/params.h"

namespace hivox {

struct SplitMergeResult {
  int64_t done = 0;     ///< blocks split (or parents merged)
  int64_t waiting = 0;  ///< wanted, but the pool or an overflow list lacked room: retried later
  int64_t invalid = 0;  ///< not in a state that allows it (e.g. no longer allocated)
};

/// Splits each allocated block of `blocks` above the finest level into its 8 children one level
/// finer, filled by trilinear interpolation of the parent (weights times `weight_scale`); the
/// parent's entry becomes Split and its block returns to the pool. A full pool makes splits
/// wait (counted), never lose data: either all 8 children exist or the parent stays.
SplitMergeResult split_blocks(VoxelBlockMap& map, std::span<const BlockRef> blocks,
                              float weight_scale = 0.5f);

/// Merges each Split parent of `parents` whose 8 children are allocated leaves: the parent gets a
/// fresh block filled by subsampling the children, the children's entries become Empty (chains
/// shortened at their tail only) and their blocks return to the pool.
SplitMergeResult merge_blocks(VoxelBlockMap& map, std::span<const BlockKey> parents);

struct RefineStats {
  int64_t evaluated = 0;  ///< blocks whose complexity was computed
  int64_t splits = 0;
  int64_t merges = 0;
  int64_t waiting = 0;  ///< splits or merges postponed for lack of room
};

class Refiner {
 public:
  explicit Refiner(const RefineParams& params = {});
  const RefineParams& params() const { return params_; }

  /// One pass (every `every_n_frames`-th call): judges `candidates` (typically the blocks the
  /// last frame touched) for splitting and their parents for merging, then merges and splits.
  /// `T_wc` is the camera that just observed them: its depth sets the noise-aware thresholds.
  RefineStats refine(VoxelBlockMap& map, std::span<const BlockRef> candidates, float truncation_m,
                     const Pose& T_wc = Pose::Identity());

  /// Complexity of pool block `ptr` under the configured criterion (-1: too little observed
  /// surface to judge).
  float complexity(const VoxelBlockMap& map, int32_t ptr, float truncation_m,
                   float* mean_weight = nullptr) const;

 private:
  RefineParams params_;
  int64_t calls_ = 0;
};

}  // namespace hivox

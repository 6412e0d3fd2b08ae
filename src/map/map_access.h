#pragma once
// Write access to a map's storage. Not installed: only the code that keeps the map's invariants
// uses it -- the map module's own edits (insertion, split, merge) and integration, which writes
// voxels and keeps each block's surface summary -- and tests that craft voxel content.

#include <cstdint>

#include "hivox/map/voxel_block_map.h"

namespace hivox {

struct MapAccess {
  /// The map's storage, writable (pointers into `map`; valid while it lives). A const map too:
  /// this header is the guard, not the map's constness (tests read the free lists through it).
  static MutableMapView storage(const VoxelBlockMap& map) { return map.storage_; }

  /// The voxels (and colours, or null) of pool block `ptr`. Whoever writes them calls
  /// refresh_surface afterwards.
  static TsdfVoxel* tsdf(VoxelBlockMap& map, int32_t ptr) {
    return map.storage_.tsdf + int64_t{ptr} * kBlockVoxels;
  }
  static ColorVoxel* color(VoxelBlockMap& map, int32_t ptr) {
    return map.storage_.color ? map.storage_.color + int64_t{ptr} * kBlockVoxels : nullptr;
  }
  /// The metadata of pool block `ptr`.
  static BlockMeta& meta(VoxelBlockMap& map, int32_t ptr) { return map.storage_.meta[ptr]; }

  /// Recomputes the surface summary of pool block `ptr` (BlockMeta::surface, which raycasting
  /// relies on) from its voxels.
  static void refresh_surface(VoxelBlockMap& map, int32_t ptr) {
    map.storage_.meta[ptr].surface = block_surface(tsdf(map, ptr));
  }

  /// Records blocks dropped by an edit that found a capacity exhausted.
  static void add_dropped_blocks(VoxelBlockMap& map, int64_t n) { map.dropped_blocks_ += n; }
};

}  // namespace hivox

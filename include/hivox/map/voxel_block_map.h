#pragma once
/// @file
/// The voxel block map: one hash table per resolution level and one voxel-block pool shared by
/// all levels. Owns the memory; kernels work on its `MapView`.

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "hivox/core/device.h"
#include "hivox/map/map_view.h"
#include "hivox/map/params.h"

namespace hivox {

/// A block coordinate at a level (the unit of allocation).
struct BlockKey {
  Vec3i pos;
  int32_t level = 0;
};
bool operator<(const BlockKey& a, const BlockKey& b);
bool operator==(const BlockKey& a, const BlockKey& b);

/// An allocated block: where its entry is and which pool block holds its voxels.
struct BlockRef {
  Vec3i pos;
  int32_t level = 0;
  int32_t entry = kNoEntry;
  int32_t ptr = kPtrEmpty;
};

/// The allocated blocks listed in a pool's metadata (`meta` for pool blocks [0, high_water)),
/// in pool order: VoxelBlockMap::allocated_blocks, and the same for a copy of the metadata (a
/// device map's, downloaded). `expected`: how many there are, when known (reserved up front).
std::vector<BlockRef> allocated_blocks(const BlockMeta* meta, int32_t high_water,
                                       int64_t expected = 0);

/// Outcome of a batched insertion; nothing is dropped silently.
struct InsertStats {
  int64_t inserted = 0;
  int64_t dropped_hash_full = 0;  ///< excess (chain) entries of a level exhausted
  int64_t dropped_pool_full = 0;  ///< voxel-block pool exhausted
  int64_t dropped() const { return dropped_hash_full + dropped_pool_full; }
};

class VoxelBlockMap {
 public:
  /// Validates `params` and reserves the tables on `device` (where every stage then runs on this
  /// map). Voxel memory is committed as blocks are used.
  explicit VoxelBlockMap(const MapParams& params, const Device& device = Device::cpu());
  ~VoxelBlockMap();
  VoxelBlockMap(const VoxelBlockMap&) = delete;
  VoxelBlockMap& operator=(const VoxelBlockMap&) = delete;

  const MapParams& params() const { return params_; }
  const Device& device() const { return device_; }
  int levels() const { return params_.levels; }
  /// Read-only plain-data view for kernels (pointers into this map's memory). Writing goes
  /// through the map's own operations (insert_blocks, split_blocks, merge_blocks) and fusion.
  MapView view() const { return storage_.read; }

  /// Inserts blocks that are not in the map yet (`keys` unique and absent), in parallel.
  /// Every new block is cleared to "unobserved". When a capacity runs out the block is dropped,
  /// counted in the result and in `dropped_blocks()`, and a warning naming the option to raise
  /// is logged once; the map stays consistent. `inserted` (optional) receives the new blocks.
  InsertStats insert_blocks(std::span<const BlockKey> keys,
                            std::vector<BlockRef>* inserted = nullptr);

  std::optional<BlockRef> find(int level, const Vec3i& pos) const;
  /// All allocated blocks (state Allocated), in pool order.
  std::vector<BlockRef> allocated_blocks() const;
  /// What pool block `ptr` holds (level -1 when free).
  const BlockMeta& block_meta(int32_t ptr) const { return meta_[static_cast<std::size_t>(ptr)]; }
  /// 1 + the largest pool index handed out so far: pool blocks [0, high water) cover all blocks.
  int32_t block_high_water() const { return *storage_.block_high_water; }
  /// Number of entries marked Split at each level.
  std::vector<int64_t> split_entries_per_level() const;

  /// The voxels of pool block `ptr` (read-only).
  const TsdfVoxel* block_tsdf(int32_t ptr) const {
    return storage_.tsdf + int64_t{ptr} * kBlockVoxels;
  }
  /// The colours of pool block `ptr`, or null when the map stores no colour.
  const ColorVoxel* block_color(int32_t ptr) const {
    return storage_.color ? storage_.color + int64_t{ptr} * kBlockVoxels : nullptr;
  }
  /// Voxel at global voxel coordinate `v` of `level`, when its block is allocated there.
  std::optional<TsdfVoxel> voxel(int level, const Vec3i& v) const;

  int64_t block_capacity() const { return params_.max_blocks; }
  int64_t blocks_in_use() const;
  std::vector<int64_t> blocks_per_level() const;
  int64_t excess_in_use(int level) const;
  /// Bytes of voxel blocks in use plus the hash tables and free lists.
  int64_t memory_bytes() const;
  /// Blocks dropped so far because a capacity ran out.
  int64_t dropped_blocks() const { return dropped_blocks_; }

  /// Empties the map (all blocks free, tables cleared).
  void clear();

 private:
  template <typename T>
  struct Reservation {
    T* data = nullptr;
    std::size_t bytes = 0;
  };
  MapParams params_;
  Device device_;
  std::array<std::vector<HashEntry>, kMaxLevels> entries_;
  std::array<std::vector<int32_t>, kMaxLevels> excess_free_;
  std::vector<int32_t> block_free_;
  std::vector<BlockMeta> meta_;
  // Counters addressed by kernels: [0, kMaxLevels) excess free counts, then the block free
  // count, then kMaxLevels per-level block counts, then the pool high-water mark.
  std::vector<int32_t> counters_;
  Reservation<TsdfVoxel> tsdf_;
  Reservation<ColorVoxel> color_;
  MutableMapView storage_;  ///< every pointer into the above; readers get storage_.read
  int64_t dropped_blocks_ = 0;

  friend struct MapAccess;  // write access for the map's own edits and fusion
};

}  // namespace hivox

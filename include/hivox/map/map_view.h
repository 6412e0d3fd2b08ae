#pragma once
/// @file
/// Plain-data view of the map for kernels (host and device) and the lookup functions written
/// once on it. A view is passed by value; it does not own memory.

#include <cstdint>

#include "hivox/core/hd.h"
#include "hivox/core/math.h"
#include "hivox/map/params.h"
#include "hivox/map/voxel.h"

namespace hivox {

/// What a hash entry's `ptr` means.
enum class EntryState {
  Allocated,  ///< ptr >= 0 indexes a voxel block in the pool
  Split,      ///< the region lives at the next finer level
  Empty,      ///< unused slot (reusable; the chain may continue through it)
  Reserved,   ///< claimed by an insertion in progress (only seen while allocating)
};

inline constexpr int32_t kPtrEmpty = -1;
inline constexpr int32_t kPtrSplit = -2;
inline constexpr int32_t kPtrReserved = -3;
inline constexpr int32_t kNoEntry = -1;  ///< end of a chain / "not found"

HIVOX_HD inline EntryState entry_state(int32_t ptr) {
  if (ptr >= 0) return EntryState::Allocated;
  if (ptr == kPtrSplit) return EntryState::Split;
  if (ptr == kPtrReserved) return EntryState::Reserved;
  return EntryState::Empty;
}

/// One slot of a level's hash table: a bucket head (index < bucket count) or an excess entry.
struct HashEntry {
  Vec3i pos;                ///< block coordinates at this entry's level
  int32_t ptr = kPtrEmpty;  ///< block index, kPtrSplit, kPtrEmpty or kPtrReserved
  int32_t next = kNoEntry;  ///< next entry of the chain (an excess index) or kNoEntry
};

/// Bucket of block coordinates: the classic spatial hash on unsigned values, so a negative
/// coordinate does not collide with its mirror image.
HIVOX_HD inline uint32_t block_hash(const Vec3i& b, uint32_t bucket_mask) {
  return ((static_cast<uint32_t>(b.x) * 73856093u) ^ (static_cast<uint32_t>(b.y) * 19349669u) ^
          (static_cast<uint32_t>(b.z) * 83492791u)) &
         bucket_mask;
}

/// A stack of free indices (voxel blocks or excess entries). Pops and pushes happen in separate
/// phases, each with atomics only.
struct FreeListView {
  int32_t* items = nullptr;
  int32_t* count = nullptr;  ///< number of free items (top of stack)
  int32_t capacity = 0;
};

/// The octants of a block (bit o: the interpolation cells whose lowest voxel has local
/// coordinates >= 4 along x where o & 1, along y where o & 2, along z where o & 4, else < 4)
/// whose cells have voxel (x, y, z) of the block as a corner: the octant of the voxel, and
/// the one below along each axis where the voxel's coordinate is 4.
HIVOX_HD constexpr unsigned voxel_octants(int x, int y, int z) {
  const unsigned mx = (x <= 4 ? 0x55u : 0u) | (x >= 4 ? 0xAAu : 0u);
  const unsigned my = (y <= 4 ? 0x33u : 0u) | (y >= 4 ? 0xCCu : 0u);
  const unsigned mz = (z <= 4 ? 0x0Fu : 0u) | (z >= 4 ? 0xF0u : 0u);
  return mx & my & mz;
}

/// The summary of a block's content that raycasting uses: which parts were observed, and where
/// observed voxels are at or behind a surface (TSDF <= 0). Where observed voxels are all
/// positive there is no surface, so rays cross such a block, or such an octant of a block
/// (voxel_octants), in one step; cells that reach into the next block are not covered.
struct BlockSurface {
  uint8_t observed = 0;  ///< bit o set: a cell of octant o has an observed corner
  uint8_t surface = 0;   ///< bit o set: a cell of octant o has an observed corner with TSDF <= 0

  /// Takes in observed voxel (x, y, z) with TSDF `tsdf`.
  HIVOX_HD void add(int x, int y, int z, int16_t tsdf) {
    const unsigned bits = voxel_octants(x, y, z);
    observed = static_cast<uint8_t>(observed | bits);
    if (tsdf <= 0) surface = static_cast<uint8_t>(surface | bits);
  }
};

/// The surface summary of a block's voxels `v` (observed: weight > 0).
HIVOX_HD inline BlockSurface block_surface(const TsdfVoxel* v) {
  BlockSurface surface;
  for (int i = 0; i < kBlockVoxels; ++i) {
    if (v[i].weight == 0) continue;
    const Vec3i c = voxel_coords(i);
    surface.add(c.x, c.y, c.z, v[i].tsdf);
  }
  return surface;
}

/// What is stored in a pool block: its coordinates, level and hash entry (level -1 = free); its
/// surface summary for raycasting; and how many frames were integrated into it since its
/// content was created (by allocation, split or merge), which refinement uses to judge only
/// settled blocks.
struct BlockMeta {
  Vec3i pos;
  int32_t entry = kNoEntry;
  int16_t level = -1;
  uint16_t updates = 0;
  BlockSurface surface;
};
static_assert(sizeof(BlockMeta) == 24);

/// One level's hash table and geometry, read-only: what lookups and readers need.
struct LevelView {
  const HashEntry* entries = nullptr;  ///< bucket_count heads followed by the excess entries
  uint32_t bucket_mask = 0;            ///< bucket_count - 1
  int32_t entry_count = 0;             ///< bucket_count + excess capacity
  float voxel_size_m = 0;
  float block_size_m = 0;
  float inv_voxel_size = 0;  ///< 1 / voxel_size_m (kernels multiply, never divide)
  float inv_block_size = 0;  ///< 1 / block_size_m
};

/// The map as readers see it (raycasting, meshing, refinement criteria, evaluation): tables,
/// voxels and block metadata, read-only.
struct MapView {
  LevelView level[kMaxLevels];
  int32_t levels = 0;
  float truncation_m = 0;             ///< MapParams::truncation_m: a TSDF of 1 is this far
  const TsdfVoxel* tsdf = nullptr;    ///< block_capacity * 512 voxels
  const ColorVoxel* color = nullptr;  ///< same layout, or null when colour is not stored
  int32_t block_capacity = 0;
  const BlockMeta* meta = nullptr;  ///< per pool block
};

/// One level's table as the map's own edits see it: entries and the free excess entries.
struct MutableLevelView {
  HashEntry* entries = nullptr;
  FreeListView excess;  ///< free excess entry indices (absolute indices in `entries`)
};

/// Write access to the map's storage, for the code that keeps its invariants: the map module's
/// edits (insertion, split, merge) and integration (voxels and their surface summaries). Only
/// `MapAccess` (src/map/map_access.h) hands it out; everyone else reads through `MapView`.
struct MutableMapView {
  MapView read;  ///< the same storage, read-only (geometry and lookups)
  MutableLevelView level[kMaxLevels];
  TsdfVoxel* tsdf = nullptr;
  ColorVoxel* color = nullptr;
  BlockMeta* meta = nullptr;
  FreeListView blocks;                   ///< free voxel-block indices
  int32_t* level_block_count = nullptr;  ///< allocated blocks per level (kMaxLevels counters)
  int32_t* block_high_water = nullptr;   ///< 1 + the largest pool index ever handed out
};

/// Index of the entry holding block `pos` at `level`, or kNoEntry. Empty slots are skipped.
HIVOX_HD inline int32_t find_entry(const LevelView& lv, const Vec3i& pos) {
  int32_t i = static_cast<int32_t>(block_hash(pos, lv.bucket_mask));
  while (i != kNoEntry) {
    const HashEntry& e = lv.entries[i];
    if (e.ptr != kPtrEmpty && e.pos == pos) return i;
    i = e.next;
  }
  return kNoEntry;
}

/// `ptr` of block `pos` at `level` (block index, kPtrSplit) or kPtrEmpty when absent.
HIVOX_HD inline int32_t find_block_ptr(const LevelView& lv, const Vec3i& pos) {
  const int32_t i = find_entry(lv, pos);
  return i == kNoEntry ? kPtrEmpty : lv.entries[i].ptr;
}

/// Block of `level` containing world point `p_w`.
HIVOX_HD inline Vec3i block_of_point(const LevelView& lv, const Vec3f& p_w) {
  return floor_to_int(p_w * lv.inv_block_size);
}

/// Splits a global voxel coordinate into block coordinates and the voxel index inside it.
HIVOX_HD inline Vec3i block_of_voxel(const Vec3i& v) {
  return {v.x >> 3, v.y >> 3, v.z >> 3};  // arithmetic shift = floor division by 8
}
HIVOX_HD inline int local_voxel_index(const Vec3i& v) {
  return voxel_index(v.x & 7, v.y & 7, v.z & 7);
}

}  // namespace hivox

#pragma once
// Map maintenance written once for CPU and CUDA drivers: free lists and lock-free insertion.
// Phases never mix: within one parallel pass there are only pops or only pushes on a free
// list, and no lookups run while entries are being inserted.

#include "hivox/core/atomic.h"
#include "hivox/core/hd.h"
#include "hivox/map/map_view.h"

namespace hivox::kernels {

/// Pops a free index, or -1 when the list is empty.
HIVOX_HD inline int32_t free_list_pop(const FreeListView& list) {
  const int32_t n = atomic_add(list.count, -1);
  if (n <= 0) {
    atomic_add(list.count, 1);
    return -1;
  }
  return list.items[n - 1];
}

/// Returns an index to the list (capacity is never exceeded: only popped items come back).
HIVOX_HD inline void free_list_push(const FreeListView& list, int32_t item) {
  const int32_t n = atomic_add(list.count, 1);
  list.items[n] = item;
}

/// Claims a slot for block `pos` at this level and leaves it `Reserved` with `pos` written.
/// The caller guarantees `pos` is not in the table and that no other thread inserts the same
/// `pos` concurrently (the two-stage allocation de-duplicates first; splits own their children).
/// Reuses an Empty slot of the chain when there is one (compare-and-swap on `ptr`), otherwise
/// appends an excess entry at the tail (compare-and-swap on `next`). Returns the entry index or
/// kNoEntry when the excess list is exhausted.
HIVOX_HD inline int32_t reserve_entry(const MutableMapView& map, int level, const Vec3i& pos) {
  const MutableLevelView& lv = map.level[level];
  int32_t i = static_cast<int32_t>(block_hash(pos, map.read.level[level].bucket_mask));
  int32_t spare = kNoEntry;  // an excess entry claimed for appending, not yet linked
  for (;;) {
    HashEntry& e = lv.entries[i];
    if (spare == kNoEntry && atomic_cas(&e.ptr, kPtrEmpty, kPtrReserved) == kPtrEmpty) {
      e.pos = pos;
      return i;
    }
    const int32_t next = atomic_load(&e.next);
    if (next != kNoEntry) {
      i = next;
      continue;
    }
    if (spare == kNoEntry) {
      spare = free_list_pop(lv.excess);
      if (spare < 0) return kNoEntry;
      HashEntry& s = lv.entries[spare];
      s.pos = pos;
      s.next = kNoEntry;
      atomic_store(&s.ptr, kPtrReserved);
    }
    const int32_t seen = atomic_cas(&e.next, kNoEntry, spare);
    if (seen == kNoEntry) return spare;
    i = seen;  // another thread appended first: continue from its entry
  }
}

/// Resets a block's voxels to "unobserved".
HIVOX_HD inline void clear_block(const MutableMapView& map, int32_t block) {
  TsdfVoxel* v = map.tsdf + static_cast<int64_t>(block) * kBlockVoxels;
  for (int i = 0; i < kBlockVoxels; ++i) v[i] = TsdfVoxel{};
  if (map.color != nullptr) {
    ColorVoxel* c = map.color + static_cast<int64_t>(block) * kBlockVoxels;
    for (int i = 0; i < kBlockVoxels; ++i) c[i] = ColorVoxel{};
  }
}

/// Takes a free pool block the caller has made sure is there (the hierarchy's edits count their
/// room first), keeping the high-water mark.
HIVOX_HD inline int32_t take_block(const MutableMapView& map) {
  const int32_t b = free_list_pop(map.blocks);
  atomic_max(map.block_high_water, b + 1);
  return b;
}

/// Returns pool block `block` to the free list, its metadata cleared (level -1 = free).
HIVOX_HD inline void return_block(const MutableMapView& map, int32_t block) {
  map.meta[block] = BlockMeta{};
  free_list_push(map.blocks, block);
}

enum class AllocResult { Allocated, HashFull, PoolFull };

/// Inserts block `pos` at `level` with a fresh (cleared) voxel block. On failure nothing is
/// left behind: a reserved slot is released to Empty (a linked excess entry stays in its chain
/// as a reusable empty slot). `entry_out` / `block_out` receive the indices on success.
/// `clear_voxels` false: the caller clears the block's voxels itself (a GPU block of threads
/// does it together) before anything reads them.
HIVOX_HD inline AllocResult allocate_block(const MutableMapView& map, int level, const Vec3i& pos,
                                           int32_t* entry_out, int32_t* block_out,
                                           bool clear_voxels = true) {
  const MutableLevelView& lv = map.level[level];
  const int32_t entry = reserve_entry(map, level, pos);
  if (entry == kNoEntry) return AllocResult::HashFull;
  const int32_t block = free_list_pop(map.blocks);
  if (block < 0) {
    atomic_store(&lv.entries[entry].ptr, kPtrEmpty);
    return AllocResult::PoolFull;
  }
  if (clear_voxels) clear_block(map, block);
  map.meta[block] = BlockMeta{pos, entry, static_cast<int16_t>(level), 0, BlockSurface{}};
  atomic_max(map.block_high_water, block + 1);
  atomic_store(&lv.entries[entry].ptr, block);
  atomic_add(&map.level_block_count[level], 1);
  *entry_out = entry;
  *block_out = block;
  return AllocResult::Allocated;
}

}  // namespace hivox::kernels

#include "hivox/map/hierarchy_edit.h"

#include <algorithm>
#include <array>
#include <vector>

#include "core/parallel.h"
#include "hivox/core/atomic.h"
#include "hivox/core/log.h"
#include "map/hierarchy_kernels.h"
#include "map/map_access.h"
#include "map/map_kernels.h"

namespace hivox {

namespace {

SplitMergeResult split_blocks_cpu(VoxelBlockMap& map, std::span<const BlockRef> blocks,
                                  float weight_scale) {
  const MutableMapView view = MapAccess::storage(map);
  SplitMergeResult result;
  // Still-allocated blocks above the finest level, in a fixed order (the same subset waits
  // whatever the thread count).
  std::vector<BlockRef> todo;
  for (const BlockRef& b : blocks) {
    const bool valid = b.level > 0 && b.level < view.read.levels && b.entry >= 0 &&
                       view.read.level[b.level].entries[b.entry].ptr == b.ptr && b.ptr >= 0 &&
                       view.read.level[b.level].entries[b.entry].pos == b.pos;
    if (valid)
      todo.push_back(b);
    else
      ++result.invalid;
  }
  std::sort(todo.begin(), todo.end(), [](const BlockRef& a, const BlockRef& b) {
    return BlockKey{a.pos, a.level} < BlockKey{b.pos, b.level};
  });
  todo.erase(std::unique(todo.begin(), todo.end(),
                         [](const BlockRef& a, const BlockRef& b) { return a.ptr == b.ptr; }),
             todo.end());
  kernels::SplitRoom room{*view.blocks.count, {}};
  for (int l = 0; l < view.read.levels; ++l) room.free_excess[l] = *view.level[l].excess.count;
  std::vector<BlockRef> go;
  for (const BlockRef& b : todo) {
    if (room.take(b.level))
      go.push_back(b);
    else
      ++result.waiting;
  }
  if (result.waiting > 0)
    log::warn_once("refine.split_waiting",
                   "voxel block pool or hash overflow list too small for all splits ({} blocks "
                   "free): splits wait and are counted in stats; raise --max-blocks",
                   *view.blocks.count);
  const int64_t n = static_cast<int64_t>(go.size());
  std::vector<std::array<int32_t, kBlockChildren>> child_block(go.size()), child_entry(go.size());
  std::vector<std::array<BlockSurface, kBlockChildren>> child_surface(go.size());

  // Splits go one parent level at a time, finest first: a split reads its neighbours at the
  // parent's level while it reserves entries one level down, so no level is read while another
  // thread writes it. (Children of coarser parents, split later, were not visible to finer
  // parents' splits before either: their entries held kPtrReserved until published.)
  for (int level = 1; level < view.read.levels; ++level) {
    std::vector<int64_t> at_level;
    for (int64_t s = 0; s < n; ++s)
      if (go[static_cast<std::size_t>(s)].level == level) at_level.push_back(s);
    const int64_t m = static_cast<int64_t>(at_level.size());
    // Pass 1: the blocks each split reads: its parent and the parent's +x/+y/+z neighbours at
    // the parent's level, and the children one level down of neighbours split before. Nothing
    // is written here, so every split reads the map as it was.
    struct Sources {
      int32_t parents[kBlockChildren];
      int32_t neighbour_children[kBlockChildren][kBlockChildren];
    };
    std::vector<Sources> sources(static_cast<std::size_t>(m));
    parallel_for(m, [&](int64_t k) {
      const BlockRef& p = go[static_cast<std::size_t>(at_level[static_cast<std::size_t>(k)])];
      Sources& src = sources[static_cast<std::size_t>(k)];
      kernels::split_sources(view.read, p, src.parents, src.neighbour_children);
    });
    // Pass 2: claim blocks and entries one level down, fill the children.
    parallel_for(m, [&](int64_t k) {
      const int64_t s = at_level[static_cast<std::size_t>(k)];
      const BlockRef& p = go[static_cast<std::size_t>(s)];
      const Sources& src = sources[static_cast<std::size_t>(k)];
      for (int c = 0; c < kBlockChildren; ++c) {
        child_entry[s][c] = kernels::reserve_entry(view, p.level - 1, child_block_pos(p.pos, c));
        child_block[s][c] = kernels::take_block(view);
        child_surface[s][c] = kernels::fill_split_child(
            view, p, src.parents, src.neighbour_children, c, child_block[s][c], weight_scale);
      }
    });
    // Pass 3: publish the children, mark the parents Split.
    parallel_for(m, [&](int64_t k) {
      const int64_t s = at_level[static_cast<std::size_t>(k)];
      const BlockRef& p = go[static_cast<std::size_t>(s)];
      const MutableLevelView& child_level = view.level[p.level - 1];
      for (int c = 0; c < kBlockChildren; ++c) {
        const int32_t b = child_block[s][c];
        view.meta[b] = BlockMeta{child_block_pos(p.pos, c), child_entry[s][c],
                                 static_cast<int16_t>(p.level - 1), 0, child_surface[s][c]};
        atomic_store(&child_level.entries[child_entry[s][c]].ptr, b);
      }
      atomic_store(&view.level[p.level].entries[p.entry].ptr, kPtrSplit);
    });
  }
  // Pass 4: the parents' blocks go back to the pool.
  for (const BlockRef& p : go) {
    kernels::return_block(view, p.ptr);
    view.level_block_count[p.level] -= 1;
    view.level_block_count[p.level - 1] += kBlockChildren;
  }
  result.done = n;
  return result;
}

SplitMergeResult merge_blocks_cpu(VoxelBlockMap& map, std::span<const BlockKey> parents) {
  const MutableMapView view = MapAccess::storage(map);
  SplitMergeResult result;
  struct Merge {
    BlockKey parent;
    int32_t entry;
    std::array<int32_t, kBlockChildren> child_entry;
    std::array<int32_t, kBlockChildren> child_block;
  };
  std::vector<BlockKey> keys(parents.begin(), parents.end());
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  std::vector<Merge> todo;
  for (const BlockKey& k : keys) {
    Merge m{k, kNoEntry, {}, {}};
    bool ok = k.level > 0 && k.level < view.read.levels;
    if (ok) {
      m.entry = find_entry(view.read.level[k.level], k.pos);
      ok = m.entry != kNoEntry && view.read.level[k.level].entries[m.entry].ptr == kPtrSplit;
    }
    for (int c = 0; ok && c < kBlockChildren; ++c) {
      const LevelView& lv = view.read.level[k.level - 1];
      m.child_entry[c] = find_entry(lv, child_block_pos(k.pos, c));
      ok = m.child_entry[c] != kNoEntry && lv.entries[m.child_entry[c]].ptr >= 0;
      if (ok) m.child_block[c] = lv.entries[m.child_entry[c]].ptr;
    }
    if (ok)
      todo.push_back(m);
    else
      ++result.invalid;
  }
  const int64_t room = *view.blocks.count;
  if (static_cast<int64_t>(todo.size()) > room) {  // each merge needs a block before it frees 8
    result.waiting = static_cast<int64_t>(todo.size()) - room;
    todo.resize(static_cast<std::size_t>(room));
  }
  const int64_t n = static_cast<int64_t>(todo.size());
  std::vector<int32_t> parent_block(todo.size());
  std::vector<BlockSurface> parent_surface(todo.size());
  // Pass 1: claim a block per parent and fill it from the children.
  parallel_for(n, [&](int64_t i) {
    const Merge& m = todo[static_cast<std::size_t>(i)];
    parent_block[i] = kernels::take_block(view);
    parent_surface[i] = kernels::fill_merged_parent(view, m.child_block.data(), parent_block[i]);
  });
  // Pass 2: publish the parents; empty the children's entries, unlinking chain tails.
  std::vector<std::array<int32_t, kBlockChildren>> unlinked(todo.size());
  parallel_for(n, [&](int64_t i) {
    const Merge& m = todo[static_cast<std::size_t>(i)];
    const int pl = m.parent.level;
    view.meta[parent_block[i]] =
        BlockMeta{m.parent.pos, m.entry, static_cast<int16_t>(pl), 0, parent_surface[i]};
    atomic_store(&view.level[pl].entries[m.entry].ptr, parent_block[i]);
    const MutableLevelView& lv = view.level[pl - 1];
    for (int c = 0; c < kBlockChildren; ++c) {
      atomic_store(&lv.entries[m.child_entry[c]].ptr, kPtrEmpty);
      const bool gone = kernels::unlink_tail_entry(view, pl - 1, m.child_entry[c],
                                                   child_block_pos(m.parent.pos, c));
      unlinked[i][c] = gone ? m.child_entry[c] : kNoEntry;
    }
  });
  // Pass 3: return the children's blocks and unlinked entries.
  for (std::size_t i = 0; i < todo.size(); ++i) {
    const Merge& m = todo[i];
    for (int c = 0; c < kBlockChildren; ++c) {
      kernels::return_block(view, m.child_block[c]);
      if (unlinked[i][c] != kNoEntry)
        kernels::free_list_push(view.level[m.parent.level - 1].excess, unlinked[i][c]);
    }
    view.level_block_count[m.parent.level] += 1;
    view.level_block_count[m.parent.level - 1] -= kBlockChildren;
  }
  result.done = n;
  return result;
}

}  // namespace

SplitMergeResult split_blocks(VoxelBlockMap& map, std::span<const BlockRef> blocks,
                              float weight_scale) {
  return dispatch(map.device(), "splitting blocks",
                  [&] { return split_blocks_cpu(map, blocks, weight_scale); });
}

SplitMergeResult merge_blocks(VoxelBlockMap& map, std::span<const BlockKey> parents) {
  return dispatch(map.device(), "merging blocks", [&] { return merge_blocks_cpu(map, parents); });
}

}  // namespace hivox

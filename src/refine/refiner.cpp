#include "hivox/refine/refiner.h"

#include <algorithm>
#include <array>

#include "hivox/core/error.h"
#include "hivox/core/log.h"
#include "hivox/core/parallel.h"
#include "map/map_kernels.h"
#include "refine/refine_kernels.h"

namespace hivox {

namespace {

constexpr int kChildren = 8;

Vec3i child_pos(const Vec3i& parent, int c) {
  return {2 * parent.x + (c & 1), 2 * parent.y + ((c >> 1) & 1), 2 * parent.z + (c >> 2)};
}

Vec3i parent_pos(const Vec3i& child) {
  return {child.x >> 1, child.y >> 1, child.z >> 1};  // arithmetic shift: floor division
}

// Pops `n` blocks the caller has checked are available, keeping the high-water mark.
int32_t pop_block(const MapView& map) {
  const int32_t b = kernels::free_list_pop(map.blocks);
  atomic_max(map.block_high_water, b + 1);
  return b;
}

void return_block(const MapView& map, int32_t block) {
  map.meta[block] = BlockMeta{};
  kernels::free_list_push(map.blocks, block);
}

}  // namespace

SplitMergeResult split_blocks(VoxelBlockMap& map, std::span<const BlockRef> blocks,
                              float weight_scale) {
  const MapView view = map.view();
  SplitMergeResult result;
  // Still-allocated blocks above the finest level, in a fixed order (the same subset waits
  // whatever the thread count).
  std::vector<BlockRef> todo;
  for (const BlockRef& b : blocks) {
    const bool valid = b.level > 0 && b.level < view.levels && b.entry >= 0 &&
                       view.level[b.level].entries[b.entry].ptr == b.ptr && b.ptr >= 0 &&
                       view.level[b.level].entries[b.entry].pos == b.pos;
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
  // Room: 8 pool blocks per split (the parent's block comes back only afterwards) and, in the
  // worst case, 8 overflow entries at the child level.
  int64_t free_blocks = *view.blocks.count;
  std::array<int64_t, kMaxLevels> free_excess{};
  for (int l = 0; l < view.levels; ++l) free_excess[l] = *view.level[l].excess.count;
  std::vector<BlockRef> go;
  for (const BlockRef& b : todo) {
    if (free_blocks >= kChildren && free_excess[b.level - 1] >= kChildren) {
      free_blocks -= kChildren;
      free_excess[b.level - 1] -= kChildren;
      go.push_back(b);
    } else {
      ++result.waiting;
    }
  }
  if (result.waiting > 0)
    log::warn_once("refine.split_waiting",
                   "voxel block pool or hash overflow list too small for all splits ({} blocks "
                   "free): splits wait and are counted in stats; raise --max-blocks",
                   *view.blocks.count);
  const int64_t n = static_cast<int64_t>(go.size());
  std::vector<std::array<int32_t, kChildren>> child_block(go.size()), child_entry(go.size());
  std::vector<std::array<BlockSurface, kChildren>> child_surface(go.size());

  // Pass 1: claim blocks and entries, fill the children. No entry of the parents' level changes
  // here, so every split reads its neighbours as they were.
  parallel_for(n, [&](int64_t s) {
    const BlockRef& p = go[static_cast<std::size_t>(s)];
    const LevelView& lv = view.level[p.level];
    int32_t parents[kChildren];
    for (int d = 0; d < kChildren; ++d) {
      if (d == 0) {
        parents[0] = p.ptr;
        continue;
      }
      const int32_t ptr =
          find_block_ptr(lv, {p.pos.x + (d & 1), p.pos.y + ((d >> 1) & 1), p.pos.z + (d >> 2)});
      parents[d] = ptr >= 0 ? ptr : kPtrEmpty;
    }
    for (int c = 0; c < kChildren; ++c) {
      child_entry[s][c] = kernels::reserve_entry(view.level[p.level - 1], child_pos(p.pos, c));
      child_block[s][c] = pop_block(view);
      child_surface[s][c] =
          kernels::fill_split_child(view, parents, c, child_block[s][c], weight_scale);
    }
  });
  // Pass 2: publish the children, mark the parents Split.
  parallel_for(n, [&](int64_t s) {
    const BlockRef& p = go[static_cast<std::size_t>(s)];
    const LevelView& child_level = view.level[p.level - 1];
    for (int c = 0; c < kChildren; ++c) {
      const int32_t b = child_block[s][c];
      view.meta[b] = BlockMeta{child_pos(p.pos, c), child_entry[s][c],
                               static_cast<int16_t>(p.level - 1), 0, child_surface[s][c]};
      atomic_store(&child_level.entries[child_entry[s][c]].ptr, b);
    }
    atomic_store(&view.level[p.level].entries[p.entry].ptr, kPtrSplit);
  });
  // Pass 3: the parents' blocks go back to the pool.
  for (const BlockRef& p : go) {
    return_block(view, p.ptr);
    view.level_block_count[p.level] -= 1;
    view.level_block_count[p.level - 1] += kChildren;
  }
  result.done = n;
  return result;
}

SplitMergeResult merge_blocks(VoxelBlockMap& map, std::span<const BlockKey> parents) {
  const MapView view = map.view();
  SplitMergeResult result;
  struct Merge {
    BlockKey parent;
    int32_t entry;
    std::array<int32_t, kChildren> child_entry;
    std::array<int32_t, kChildren> child_block;
  };
  std::vector<BlockKey> keys(parents.begin(), parents.end());
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  std::vector<Merge> todo;
  for (const BlockKey& k : keys) {
    Merge m{k, kNoEntry, {}, {}};
    bool ok = k.level > 0 && k.level < view.levels;
    if (ok) {
      m.entry = find_entry(view.level[k.level], k.pos);
      ok = m.entry != kNoEntry && view.level[k.level].entries[m.entry].ptr == kPtrSplit;
    }
    for (int c = 0; ok && c < kChildren; ++c) {
      const LevelView& lv = view.level[k.level - 1];
      m.child_entry[c] = find_entry(lv, child_pos(k.pos, c));
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
    parent_block[i] = pop_block(view);
    parent_surface[i] = kernels::fill_merged_parent(view, m.child_block.data(), parent_block[i]);
  });
  // Pass 2: publish the parents; empty the children's entries, unlinking chain tails.
  std::vector<std::array<int32_t, kChildren>> unlinked(todo.size());
  parallel_for(n, [&](int64_t i) {
    const Merge& m = todo[static_cast<std::size_t>(i)];
    const int pl = m.parent.level;
    view.meta[parent_block[i]] =
        BlockMeta{m.parent.pos, m.entry, static_cast<int16_t>(pl), 0, parent_surface[i]};
    atomic_store(&view.level[pl].entries[m.entry].ptr, parent_block[i]);
    const LevelView& lv = view.level[pl - 1];
    for (int c = 0; c < kChildren; ++c) {
      atomic_store(&lv.entries[m.child_entry[c]].ptr, kPtrEmpty);
      const bool gone =
          kernels::unlink_tail_entry(lv, m.child_entry[c], child_pos(m.parent.pos, c));
      unlinked[i][c] = gone ? m.child_entry[c] : kNoEntry;
    }
  });
  // Pass 3: return the children's blocks and unlinked entries.
  for (std::size_t i = 0; i < todo.size(); ++i) {
    const Merge& m = todo[i];
    for (int c = 0; c < kChildren; ++c) {
      return_block(view, m.child_block[c]);
      if (unlinked[i][c] != kNoEntry)
        kernels::free_list_push(view.level[m.parent.level - 1].excess, unlinked[i][c]);
    }
    view.level_block_count[m.parent.level] += 1;
    view.level_block_count[m.parent.level - 1] -= kChildren;
  }
  result.done = n;
  return result;
}

Refiner::Refiner(const RefineParams& params) : params_(params) {
  params_.validate();
}

float Refiner::complexity(const VoxelBlockMap& map, int32_t ptr, float truncation_m,
                          float* mean_weight) const {
  const TsdfVoxel* v = map.block_tsdf(ptr);
  switch (params_.criterion) {
    case RefineCriterion::Detail:
      return kernels::block_detail_m(v, truncation_m, params_.min_weight, params_.min_samples,
                                     mean_weight);
    case RefineCriterion::DetCov:
      return kernels::block_det_cov(v, params_.min_weight);
  }
  return -1.0f;
}

RefineStats Refiner::refine(VoxelBlockMap& map, std::span<const BlockRef> candidates,
                            float truncation_m, const Pose& T_wc) {
  RefineStats stats;
  if (map.levels() < 2 || (calls_++ % params_.every_n_frames) != 0) return stats;
  const MapView view = map.view();
  const int top = view.levels - 1;
  auto settled = [&](int32_t ptr) { return view.meta[ptr].updates >= params_.min_updates; };
  // Depth of a block's centre from the camera that just saw it (for the noise model).
  const Rigid3f T_cw = to_rigid3f(T_wc.inverse());
  auto depth_of = [&](const Vec3i& pos, int level) {
    const float b = view.level[level].block_size_m;
    const Vec3f centre{(pos.x + 0.5f) * b, (pos.y + 0.5f) * b, (pos.z + 0.5f) * b};
    return (T_cw * centre).z;
  };

  // Split candidates: settled blocks above the finest level with complex surface.
  std::vector<float> c(candidates.size(), -1.0f), w(candidates.size(), 0.0f);
  parallel_for(static_cast<int64_t>(candidates.size()), [&](int64_t i) {
    const BlockRef& b = candidates[static_cast<std::size_t>(i)];
    if (b.ptr >= 0 && b.level > 0 && settled(b.ptr))
      c[i] = complexity(map, b.ptr, truncation_m, &w[i]);
  });
  std::vector<BlockRef> splits;
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    const BlockRef& b = candidates[i];
    if (b.level > 0 && c[i] > params_.split_level(depth_of(b.pos, b.level), w[i]))
      splits.push_back(b);
  }
  stats.evaluated = static_cast<int64_t>(candidates.size());

  // Merge candidates: the split parents of touched blocks below the coarsest level, when all 8
  // children are settled leaves with simple surface.
  std::vector<BlockKey> parents;
  for (const BlockRef& b : candidates)
    if (b.level < top) parents.push_back({parent_pos(b.pos), b.level + 1});
  std::sort(parents.begin(), parents.end());
  parents.erase(std::unique(parents.begin(), parents.end()), parents.end());
  std::vector<uint8_t> mergeable(parents.size(), 0);
  parallel_for(static_cast<int64_t>(parents.size()), [&](int64_t i) {
    const BlockKey& p = parents[static_cast<std::size_t>(i)];
    if (find_block_ptr(view.level[p.level], p.pos) != kPtrSplit) return;
    const float level = params_.merge_level(depth_of(p.pos, p.level));
    for (int k = 0; k < kChildren; ++k) {
      const int32_t ptr = find_block_ptr(view.level[p.level - 1], child_pos(p.pos, k));
      if (ptr < 0) return;
      const float c = complexity(map, ptr, truncation_m);
      // A child with too little surface to judge holds nothing a merge could lose, however
      // young: the children of a table top's block that lie below the band seen from above are
      // never integrated, and waiting for them to settle kept the flat top split for good.
      if (c < 0.0f) continue;
      if (!settled(ptr) || c >= level) return;
    }
    mergeable[i] = 1;
  });
  std::vector<BlockKey> merges;
  for (std::size_t i = 0; i < parents.size(); ++i)
    if (mergeable[i]) merges.push_back(parents[i]);
  stats.evaluated += static_cast<int64_t>(parents.size());

  const SplitMergeResult m = merge_blocks(map, merges);
  const SplitMergeResult s = split_blocks(map, splits, params_.split_weight_scale);
  stats.merges = m.done;
  stats.splits = s.done;
  stats.waiting = m.waiting + s.waiting;
  return stats;
}

}  // namespace hivox

#include "hivox/map/stored_map.h"

#include <algorithm>
#include <cstdlib>
#include <optional>

#include <fmt/format.h>

#include "core/parallel.h"
#include "hivox/core/atomic.h"
#include "hivox/core/error.h"
#include "hivox/map/hierarchy_edit.h"
#include "map/map_access.h"
#include "map/map_kernels.h"

namespace hivox {

namespace {

bool zyx_less(const Vec3i& a, const Vec3i& b) {
  return BlockKey{a, 0} < BlockKey{b, 0};
}

std::string key_text(const BlockKey& k) {
  return fmt::format("block ({}, {}, {}) of level {}", k.pos.x, k.pos.y, k.pos.z, k.level);
}

/// Every key of the content with what it is, sorted, for look-ups while checking.
class Content {
 public:
  enum class Kind : uint8_t { Block, Split };

  Content(std::span<const BlockKey> blocks, std::span<const BlockKey> splits) {
    keys_.reserve(blocks.size() + splits.size());
    for (const BlockKey& k : blocks) keys_.push_back({k, Kind::Block});
    for (const BlockKey& k : splits) keys_.push_back({k, Kind::Split});
    std::sort(keys_.begin(), keys_.end(),
              [](const Entry& a, const Entry& b) { return a.key < b.key; });
  }

  /// The first duplicated key, if any.
  std::optional<BlockKey> duplicate() const {
    for (std::size_t i = 1; i < keys_.size(); ++i)
      if (keys_[i].key == keys_[i - 1].key) return keys_[i].key;
    return std::nullopt;
  }

  std::optional<Kind> find(const BlockKey& k) const {
    const auto it =
        std::lower_bound(keys_.begin(), keys_.end(), k,
                         [](const Entry& e, const BlockKey& key) { return e.key < key; });
    if (it == keys_.end() || !(it->key == k)) return std::nullopt;
    return it->kind;
  }

  /// Why the content is not a valid hierarchy of `levels` levels, or empty.
  std::string problem(int levels) const {
    for (const Entry& e : keys_) {
      const BlockKey& k = e.key;
      if (k.level < 0 || k.level >= levels)
        return fmt::format("{}: the map has {} level(s)", key_text(k), levels);
      for (int a = 0; a < 3; ++a)
        if (std::abs(static_cast<int64_t>(k.pos[a])) > kMaxStoredBlockCoord)
          return fmt::format("{}: coordinate beyond +-{}", key_text(k), kMaxStoredBlockCoord);
    }
    if (const std::optional<BlockKey> d = duplicate())
      return fmt::format("{} is stored twice", key_text(*d));
    for (const Entry& e : keys_) {
      const BlockKey& k = e.key;
      if (e.kind == Kind::Split) {
        if (k.level == 0)
          return fmt::format("{} is split, but it is the finest level", key_text(k));
        for (int c = 0; c < kBlockChildren; ++c)
          if (!find({child_block_pos(k.pos, c), k.level - 1}))
            return fmt::format("{} is split, but its child ({}, {}, {}) is missing", key_text(k),
                               child_block_pos(k.pos, c).x, child_block_pos(k.pos, c).y,
                               child_block_pos(k.pos, c).z);
      }
      // The nearest stored ancestor must be split: a stored block above would hold this region
      // a second time.
      Vec3i p = k.pos;
      for (int l = k.level + 1; l < levels; ++l) {
        p = parent_block_pos(p);
        const std::optional<Kind> kind = find({p, l});
        if (!kind) continue;
        if (*kind == Kind::Block)
          return fmt::format(
              "{} lies inside the block ({}, {}, {}) of level {}: its region is "
              "stored twice",
              key_text(k), p.x, p.y, p.z, l);
        break;
      }
    }
    return {};
  }

 private:
  struct Entry {
    BlockKey key;
    Kind kind;
  };
  std::vector<Entry> keys_;
};

}  // namespace

std::vector<BlockRef> sorted_blocks(const VoxelBlockMap& map, int level) {
  std::vector<BlockRef> out;
  for (const BlockRef& b : map.allocated_blocks())
    if (b.level == level) out.push_back(b);
  std::sort(out.begin(), out.end(),
            [](const BlockRef& a, const BlockRef& b) { return zyx_less(a.pos, b.pos); });
  return out;
}

std::vector<Vec3i> sorted_split_entries(const VoxelBlockMap& map, int level) {
  std::vector<Vec3i> out;
  if (level < 0 || level >= map.levels()) return out;
  const LevelView& lv = map.view().level[level];
  for (int32_t i = 0; i < lv.entry_count; ++i)
    if (entry_state(lv.entries[i].ptr) == EntryState::Split) out.push_back(lv.entries[i].pos);
  std::sort(out.begin(), out.end(), zyx_less);
  return out;
}

void restore_blocks(VoxelBlockMap& map, std::span<const BlockKey> blocks,
                    std::span<const BlockKey> splits, const FillStoredBlock& fill,
                    std::string_view what) {
  const std::vector<int64_t> splits_now = map.split_entries_per_level();
  int64_t split_count = 0;
  for (const int64_t n : splits_now) split_count += n;
  if (map.blocks_in_use() != 0 || split_count != 0)
    fail(ErrorCode::InvalidArgument, "{}: a map is restored only into an empty map", what);
  const std::string problem = Content(blocks, splits).problem(map.levels());
  if (!problem.empty()) fail(ErrorCode::InvalidData, "{}: {}", what, problem);
  const MapParams& p = map.params();
  if (static_cast<int64_t>(blocks.size()) > p.max_blocks)
    fail(ErrorCode::OutOfCapacity,
         "{}: the map holds {} blocks, more than the voxel-block pool's {} (raise --max-blocks)",
         what, blocks.size(), p.max_blocks);

  std::vector<BlockRef> inserted;
  const InsertStats stats = map.insert_blocks(blocks, &inserted);
  // Split entries: claimed like a block's entry, then marked Split.
  const MutableMapView view = MapAccess::storage(map);
  bool entries_full = stats.dropped_hash_full > 0;
  for (const BlockKey& k : splits) {
    if (entries_full) break;
    const int32_t e = kernels::reserve_entry(view, k.level, k.pos);
    if (e == kNoEntry) {
      entries_full = true;
      break;
    }
    atomic_store(&view.level[k.level].entries[e].ptr, kPtrSplit);
  }
  if (entries_full || stats.dropped() > 0) {
    map.clear();
    fail(ErrorCode::OutOfCapacity,
         "{}: the hash table of a level cannot hold the map's blocks (raise --hash-excess or "
         "--hash-buckets)",
         what);
  }
  // insert_blocks returns the new blocks in the order of the keys (all were inserted).
  parallel_for(static_cast<int64_t>(inserted.size()), [&](int64_t i) {
    const int32_t ptr = inserted[static_cast<std::size_t>(i)].ptr;
    fill(static_cast<std::size_t>(i), MapAccess::tsdf(map, ptr), MapAccess::color(map, ptr),
         &MapAccess::meta(map, ptr).updates);
    MapAccess::refresh_surface(map, ptr);
  });
}

}  // namespace hivox

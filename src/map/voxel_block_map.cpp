#include "hivox/map/voxel_block_map.h"

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <numeric>
#include <tuple>

#if defined(__linux__)
#include <sys/mman.h>
#endif

#include "core/parallel.h"
#include "hivox/core/error.h"
#include "hivox/core/log.h"
#include "map/map_kernels.h"

namespace hivox {

bool operator<(const BlockKey& a, const BlockKey& b) {
  return std::tie(a.level, a.pos.z, a.pos.y, a.pos.x) <
         std::tie(b.level, b.pos.z, b.pos.y, b.pos.x);
}
bool operator==(const BlockKey& a, const BlockKey& b) {
  return a.level == b.level && a.pos == b.pos;
}

namespace {

// Large zeroed reservation whose pages are committed only when a block is first written, so
// memory in use follows the number of blocks, not the capacity. On Linux it is an anonymous
// mapping marked for transparent huge pages: one fault per 2 MiB instead of per 4 KiB when
// blocks are first used (a measurable share of fusion time otherwise).
struct LazyBuffer {
  void* data = nullptr;
  std::size_t bytes = 0;
};

LazyBuffer reserve_lazily(std::size_t bytes, const char* what) {
  LazyBuffer b;
  b.bytes = bytes;
#if defined(__linux__)
  b.data = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE,
                -1, 0);
  if (b.data == MAP_FAILED) b.data = nullptr;
  if (b.data != nullptr) madvise(b.data, bytes, MADV_HUGEPAGE);  // a hint; failure is harmless
#else
  b.data = std::calloc(bytes, 1);
#endif
  if (b.data == nullptr)
    fail(ErrorCode::OutOfCapacity, "cannot reserve {} MiB for {}; lower --max-blocks", bytes >> 20,
         what);
  return b;
}

void release(void* data, std::size_t bytes) {
  if (data == nullptr) return;
#if defined(__linux__)
  munmap(data, bytes);
#else
  (void)bytes;
  std::free(data);
#endif
}

constexpr int kBlockFreeCounter = kMaxLevels;
constexpr int kLevelCountBase = kMaxLevels + 1;
constexpr int kHighWaterCounter = 2 * kMaxLevels + 1;

}  // namespace

VoxelBlockMap::VoxelBlockMap(const MapParams& params, const Device& device)
    : params_(params), device_(device) {
  params_.validate();
  // The map's storage below is host memory: a map on another device needs that device's backend.
  if (!device_.is_cpu()) {
    device_.require_available();
    no_implementation(device_, "a voxel block map");
  }
  counters_.assign(2 * kMaxLevels + 2, 0);
  const auto voxels = static_cast<std::size_t>(params_.max_blocks * kBlockVoxels);
  const LazyBuffer tsdf = reserve_lazily(voxels * sizeof(TsdfVoxel), "TSDF voxels");
  tsdf_ = {static_cast<TsdfVoxel*>(tsdf.data), tsdf.bytes};
  if (params_.store_color) {
    const LazyBuffer color = reserve_lazily(voxels * sizeof(ColorVoxel), "colour voxels");
    color_ = {static_cast<ColorVoxel*>(color.data), color.bytes};
  }
  MapView& read = storage_.read;
  read.levels = params_.levels;
  read.truncation_m = params_.truncation_m;
  storage_.tsdf = tsdf_.data;
  storage_.color = color_.data;
  read.tsdf = storage_.tsdf;
  read.color = storage_.color;
  read.block_capacity = static_cast<int32_t>(params_.max_blocks);
  storage_.level_block_count = counters_.data() + kLevelCountBase;
  block_free_.resize(static_cast<std::size_t>(params_.max_blocks));
  meta_.resize(static_cast<std::size_t>(params_.max_blocks));
  storage_.meta = meta_.data();
  read.meta = storage_.meta;
  storage_.block_high_water = counters_.data() + kHighWaterCounter;
  storage_.blocks = {block_free_.data(), counters_.data() + kBlockFreeCounter,
                     static_cast<int32_t>(params_.max_blocks)};
  for (int l = 0; l < params_.levels; ++l) {
    const int64_t total = params_.buckets_per_level + params_.excess_per_level;
    entries_[l].resize(static_cast<std::size_t>(total));
    excess_free_[l].resize(static_cast<std::size_t>(params_.excess_per_level));
    MutableLevelView& edit = storage_.level[l];
    edit.entries = entries_[l].data();
    edit.excess = {excess_free_[l].data(), counters_.data() + l,
                   static_cast<int32_t>(params_.excess_per_level)};
    LevelView& lv = read.level[l];
    lv.entries = edit.entries;
    lv.bucket_mask = static_cast<uint32_t>(params_.buckets_per_level - 1);
    lv.entry_count = static_cast<int32_t>(total);
    lv.voxel_size_m = params_.voxel_size_at(l);
    lv.block_size_m = params_.block_size_at(l);
    lv.inv_voxel_size = 1.0f / lv.voxel_size_m;
    lv.inv_block_size = 1.0f / lv.block_size_m;
  }
  clear();
}

VoxelBlockMap::~VoxelBlockMap() {
  release(tsdf_.data, tsdf_.bytes);
  release(color_.data, color_.bytes);
}

void VoxelBlockMap::clear() {
  // Free stacks pop from the top: fill them so blocks 0, 1, 2, ... come out first, which keeps
  // the committed voxel memory compact.
  const int32_t n = static_cast<int32_t>(params_.max_blocks);
  for (int32_t i = 0; i < n; ++i) block_free_[i] = n - 1 - i;
  counters_[kBlockFreeCounter] = n;
  counters_[kHighWaterCounter] = 0;
  std::fill(meta_.begin(), meta_.end(), BlockMeta{});
  for (int l = 0; l < params_.levels; ++l) {
    std::fill(entries_[l].begin(), entries_[l].end(), HashEntry{});
    const int32_t buckets = static_cast<int32_t>(params_.buckets_per_level);
    const int32_t excess = static_cast<int32_t>(params_.excess_per_level);
    for (int32_t i = 0; i < excess; ++i) excess_free_[l][i] = buckets + excess - 1 - i;
    counters_[l] = excess;
    counters_[kLevelCountBase + l] = 0;
  }
  dropped_blocks_ = 0;
}

InsertStats VoxelBlockMap::insert_blocks(std::span<const BlockKey> keys,
                                         std::vector<BlockRef>* inserted) {
  const int64_t n = static_cast<int64_t>(keys.size());
  std::vector<BlockRef> refs(keys.size());
  std::vector<uint8_t> outcome(keys.size());
  const MutableMapView map = storage_;
  const BlockKey* key = keys.data();
  BlockRef* ref = refs.data();
  uint8_t* result = outcome.data();
  parallel_for(device_, n, [=] HIVOX_HD(int64_t i) {
    const BlockKey& k = key[i];
    int32_t entry = kNoEntry, block = kPtrEmpty;
    const auto r = kernels::allocate_block(map, k.level, k.pos, &entry, &block);
    result[i] = static_cast<uint8_t>(r);
    ref[i] = {k.pos, k.level, entry, block};
  });
  InsertStats stats;
  if (inserted) inserted->reserve(inserted->size() + keys.size());
  for (std::size_t i = 0; i < keys.size(); ++i) {
    switch (static_cast<kernels::AllocResult>(outcome[i])) {
      case kernels::AllocResult::Allocated:
        ++stats.inserted;
        if (inserted) inserted->push_back(refs[i]);
        break;
      case kernels::AllocResult::HashFull:
        ++stats.dropped_hash_full;
        break;
      case kernels::AllocResult::PoolFull:
        ++stats.dropped_pool_full;
        break;
    }
  }
  dropped_blocks_ += stats.dropped();
  if (stats.dropped_pool_full > 0)
    log::warn_once("map.pool_full",
                   "voxel block pool is full ({} blocks): new blocks are being dropped and counted "
                   "in stats (dropped_blocks); raise --max-blocks",
                   params_.max_blocks);
  if (stats.dropped_hash_full > 0)
    log::warn_once("map.excess_full",
                   "hash table overflow list is full ({} entries per level): new blocks are being "
                   "dropped and counted in stats (dropped_blocks); raise --hash-excess or "
                   "--hash-buckets",
                   params_.excess_per_level);
  return stats;
}

std::optional<BlockRef> VoxelBlockMap::find(int level, const Vec3i& pos) const {
  if (level < 0 || level >= params_.levels) return std::nullopt;
  const LevelView& lv = storage_.read.level[level];
  const int32_t e = find_entry(lv, pos);
  if (e == kNoEntry) return std::nullopt;
  return BlockRef{pos, level, e, lv.entries[e].ptr};
}

std::vector<BlockRef> allocated_blocks(const BlockMeta* meta, int32_t high_water,
                                       int64_t expected) {
  std::vector<BlockRef> out;
  out.reserve(static_cast<std::size_t>(expected));
  for (int32_t ptr = 0; ptr < high_water; ++ptr) {
    const BlockMeta& m = meta[ptr];
    if (m.level >= 0) out.push_back({m.pos, m.level, m.entry, ptr});
  }
  return out;
}

std::vector<BlockRef> VoxelBlockMap::allocated_blocks() const {
  return hivox::allocated_blocks(meta_.data(), block_high_water(), blocks_in_use());
}

std::vector<int64_t> VoxelBlockMap::split_entries_per_level() const {
  std::vector<int64_t> out(params_.levels, 0);
  for (int l = 0; l < params_.levels; ++l)
    for (const HashEntry& e : entries_[l]) out[l] += e.ptr == kPtrSplit;
  return out;
}

std::optional<TsdfVoxel> VoxelBlockMap::voxel(int level, const Vec3i& v) const {
  if (level < 0 || level >= params_.levels) return std::nullopt;
  const int32_t ptr = find_block_ptr(storage_.read.level[level], block_of_voxel(v));
  if (ptr < 0) return std::nullopt;
  return block_tsdf(ptr)[local_voxel_index(v)];
}

int64_t VoxelBlockMap::blocks_in_use() const {
  return params_.max_blocks - counters_[kBlockFreeCounter];
}

std::vector<int64_t> VoxelBlockMap::blocks_per_level() const {
  std::vector<int64_t> out(params_.levels);
  for (int l = 0; l < params_.levels; ++l) out[l] = counters_[kLevelCountBase + l];
  return out;
}

int64_t VoxelBlockMap::excess_in_use(int level) const {
  return params_.excess_per_level - counters_[level];
}

int64_t VoxelBlockMap::memory_bytes() const {
  const int64_t block_bytes = int64_t{kBlockVoxels} * params_.bytes_per_voxel();
  int64_t bytes = blocks_in_use() * block_bytes;
  bytes +=
      static_cast<int64_t>(block_free_.size() * sizeof(int32_t) + meta_.size() * sizeof(BlockMeta));
  for (int l = 0; l < params_.levels; ++l)
    bytes += static_cast<int64_t>(entries_[l].size() * sizeof(HashEntry) +
                                  excess_free_[l].size() * sizeof(int32_t));
  return bytes;
}

}  // namespace hivox

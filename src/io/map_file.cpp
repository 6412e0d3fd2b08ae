#include "hivox/io/map_file.h"

#include <zstd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cstdio>
#include <cstring>
#include <memory>
#include <span>
#include <string_view>

#define XXH_INLINE_ALL
#include <xxhash.h>

#include <fmt/format.h>

#include "core/parallel.h"
#include "hivox/core/error.h"
#include "hivox/core/version.h"
#include "hivox/io/atomic_file.h"

namespace hivox {

namespace fs = std::filesystem;

static_assert(std::endian::native == std::endian::little,
              "map files are little-endian; a big-endian build would swap every field");

namespace {

// The layout (docs/map-files.md): header, chunk table, zstd chunks, checksum, end marker.
constexpr std::array<char, 8> kMagic = {'H', 'I', 'V', 'O', 'X', 'M', 'A', 'P'};
constexpr std::array<char, 8> kEndMagic = {'H', 'V', 'X', 'E', 'N', 'D', '\0', '\0'};
constexpr std::size_t kTrailerBytes = 8 + kEndMagic.size();  // checksum, end marker
constexpr std::size_t kVersionBytes = 16;
/// Raw bytes per chunk of a level's index (coordinates and update counts).
constexpr uint64_t kIndexChunkBytes = 1u << 20;
/// Blocks per voxel chunk. A chunk holds whole blocks, so saving fills each chunk straight from
/// the map and loading writes it straight into the map, a chunk per thread at a time: neither
/// makes a copy of a level. Chunks compress and decompress in parallel.
constexpr int64_t kGroupBlocks = 128;
constexpr int kZstdLevel = 1;
constexpr uint32_t kHasPose = 1, kHasCamera = 2;

/// Bytes of one block's voxels in a chunk: TSDF and weight (2 + 2 B), colour (4 B).
uint64_t block_bytes(bool color) {
  return uint64_t{kBlockVoxels} * (color ? 8 : 4);
}

/// A level's counts and the chunks they make: first the index (Split entries' and blocks'
/// coordinates, blocks' update counts) in chunks of kIndexChunkBytes, then the voxels in chunks
/// of kGroupBlocks blocks, field by field inside each (all TSDF values, all weights, all colours).
struct LevelCounts {
  int64_t blocks = 0, splits = 0;
  uint64_t index_bytes() const {
    return 12 * static_cast<uint64_t>(splits + blocks) + 2 * static_cast<uint64_t>(blocks);
  }
  int64_t index_chunks() const {
    return static_cast<int64_t>((index_bytes() + kIndexChunkBytes - 1) / kIndexChunkBytes);
  }
  int64_t voxel_chunks() const { return (blocks + kGroupBlocks - 1) / kGroupBlocks; }
  int64_t chunks() const { return index_chunks() + voxel_chunks(); }
  /// Blocks in voxel chunk `k`.
  int64_t group_blocks(int64_t k) const {
    return std::min(kGroupBlocks, blocks - k * kGroupBlocks);
  }
  /// Raw bytes of chunk `k` (index chunks first).
  uint64_t chunk_raw_bytes(int64_t k, bool color) const {
    if (k < index_chunks())
      return std::min(kIndexChunkBytes,
                      index_bytes() - static_cast<uint64_t>(k) * kIndexChunkBytes);
    return static_cast<uint64_t>(group_blocks(k - index_chunks())) * block_bytes(color);
  }
};

uint64_t checksum(std::span<const uint8_t> bytes) {
  return XXH3_64bits(bytes.data(), bytes.size());
}

class Writer {
 public:
  template <typename T>
  void put(const T& v) {
    const auto* p = reinterpret_cast<const uint8_t*>(&v);
    bytes_.insert(bytes_.end(), p, p + sizeof(T));
  }
  void put_bytes(const void* data, std::size_t n) {
    const auto* p = static_cast<const uint8_t*>(data);
    bytes_.insert(bytes_.end(), p, p + n);
  }
  std::vector<uint8_t>& bytes() { return bytes_; }

 private:
  std::vector<uint8_t> bytes_;
};

/// Bounds-checked reading of the header: a field past the end is the file's error.
class Reader {
 public:
  Reader(std::span<const uint8_t> bytes, const std::string& what) : bytes_(bytes), what_(what) {}
  template <typename T>
  T get(const char* field) {
    T v;
    need(sizeof(T), field);
    std::memcpy(&v, bytes_.data() + at_, sizeof(T));
    at_ += sizeof(T);
    return v;
  }
  std::span<const uint8_t> get_bytes(std::size_t n, const char* field) {
    need(n, field);
    const std::span<const uint8_t> out = bytes_.subspan(at_, n);
    at_ += n;
    return out;
  }
  std::size_t at() const { return at_; }

 private:
  void need(std::size_t n, const char* field) const {
    if (n > bytes_.size() - at_)
      fail(ErrorCode::InvalidData, "{}: the header ends inside {} (truncated or corrupted)", what_,
           field);
  }
  std::span<const uint8_t> bytes_;
  std::size_t at_ = 0;
  const std::string& what_;
};

/// What a level's chunks are made from.
struct LevelContent {
  std::vector<Vec3i> splits;
  std::vector<BlockRef> blocks;
  std::vector<uint8_t> index;  ///< the raw index
};

LevelContent level_content(const VoxelBlockMap& map, int level) {
  LevelContent c;
  c.splits = sorted_split_entries(map, level);
  c.blocks = sorted_blocks(map, level);
  LevelCounts counts{static_cast<int64_t>(c.blocks.size()), static_cast<int64_t>(c.splits.size())};
  c.index.resize(counts.index_bytes());
  uint8_t* out = c.index.data();
  auto put_key = [&](const Vec3i& p) {
    const int32_t xyz[3] = {p.x, p.y, p.z};
    std::memcpy(out, xyz, sizeof xyz);
    out += sizeof xyz;
  };
  for (const Vec3i& p : c.splits) put_key(p);
  for (const BlockRef& b : c.blocks) put_key(b.pos);
  for (const BlockRef& b : c.blocks) {
    const uint16_t updates = map.block_meta(b.ptr).updates;
    std::memcpy(out, &updates, 2);
    out += 2;
  }
  return c;
}

/// The raw voxel chunk of `n` blocks from `blocks`: their TSDF values, weights, colours.
void fill_voxel_chunk(const VoxelBlockMap& map, const BlockRef* blocks, int64_t n, bool color,
                      uint8_t* out) {
  auto* tsdf = reinterpret_cast<int16_t*>(out);
  auto* weight = reinterpret_cast<uint16_t*>(out + 2 * kBlockVoxels * n);
  uint8_t* rgbw = out + 4 * kBlockVoxels * n;
  for (int64_t i = 0; i < n; ++i) {
    const TsdfVoxel* v = map.block_tsdf(blocks[i].ptr);
    for (int k = 0; k < kBlockVoxels; ++k) {
      tsdf[i * kBlockVoxels + k] = v[k].tsdf;
      weight[i * kBlockVoxels + k] = v[k].weight;
    }
    if (color)
      std::memcpy(rgbw + i * kBlockVoxels * 4, map.block_color(blocks[i].ptr),
                  kBlockVoxels * sizeof(ColorVoxel));
  }
}

/// The inverse: block `i` of a raw voxel chunk of `n` blocks into the map's storage.
void read_voxel_chunk(const uint8_t* in, int64_t n, int64_t i, bool color, TsdfVoxel* tsdf,
                      ColorVoxel* rgb) {
  int16_t t[kBlockVoxels];
  uint16_t w[kBlockVoxels];
  std::memcpy(t, in + 2 * kBlockVoxels * i, sizeof t);
  std::memcpy(w, in + 2 * kBlockVoxels * (n + i), sizeof w);
  for (int k = 0; k < kBlockVoxels; ++k) tsdf[k] = {t[k], w[k]};
  if (color && rgb != nullptr)
    std::memcpy(rgb, in + 4 * kBlockVoxels * n + 4 * kBlockVoxels * i,
                kBlockVoxels * sizeof(ColorVoxel));
}

uint32_t sampling_code(DepthSampling s) {
  return s == DepthSampling::Nearest ? 0u : 1u;
}

/// The header fields, parsed and checked; the chunk table follows them.
struct Header {
  MapFileInfo info;
  std::vector<LevelCounts> counts;
};

/// Checks the start of a file: magic and format version.
void check_start(std::span<const uint8_t> bytes, const std::string& what) {
  if (bytes.size() < kMagic.size() + 4 ||
      std::memcmp(bytes.data(), kMagic.data(), kMagic.size()) != 0)
    fail(ErrorCode::InvalidData, "{}: not a hivox map file (no HIVOXMAP magic at its start)", what);
  uint32_t version = 0;
  std::memcpy(&version, bytes.data() + kMagic.size(), 4);
  if (version == 0 || version > kMapFileVersion)
    fail(ErrorCode::Unsupported,
         "{}: map file format version {}; this hivox ({}) reads versions 1 to {}{}", what, version,
         library_version(), kMapFileVersion,
         version > kMapFileVersion ? " (written by a newer hivox? update it to read this file)"
                                   : "");
}

/// Checks the end of a whole file: end marker (truncation) and checksum (any changed byte).
void check_end(std::span<const uint8_t> bytes, const std::string& what) {
  if (bytes.size() < kMagic.size() + 4 + kTrailerBytes ||
      std::memcmp(bytes.data() + bytes.size() - kEndMagic.size(), kEndMagic.data(),
                  kEndMagic.size()) != 0)
    fail(ErrorCode::InvalidData,
         "{}: no end marker: the file is truncated (an interrupted copy?) or corrupted", what);
  const std::size_t body = bytes.size() - kTrailerBytes;
  uint64_t stored = 0;
  std::memcpy(&stored, bytes.data() + body, 8);
  if (checksum(bytes.first(body)) != stored)
    fail(ErrorCode::InvalidData,
         "{}: checksum mismatch: the file is corrupted (some byte differs from what was written)",
         what);
}

Header parse_header(Reader& r, const std::string& what, int64_t file_bytes) {
  Header h;
  MapFileInfo& info = h.info;
  info.file_bytes = file_bytes;
  r.get_bytes(kMagic.size(), "the magic");
  info.format_version = r.get<uint32_t>("the format version");
  const std::span<const uint8_t> version = r.get_bytes(kVersionBytes, "the library version");
  info.library_version.assign(
      reinterpret_cast<const char*>(version.data()),
      strnlen(reinterpret_cast<const char*>(version.data()), kVersionBytes));
  auto bad = [&](const std::string& problem) {
    fail(ErrorCode::InvalidData, "{}: {} (corrupted, or not written by hivox)", what, problem);
  };
  MapParams& m = info.map;
  m.levels = static_cast<int>(r.get<uint32_t>("the level count"));
  m.voxel_size_m = r.get<float>("the voxel size");
  m.truncation_m = r.get<float>("the truncation");
  const auto block_side = r.get<uint32_t>("the block side");
  const auto tsdf_bytes = r.get<uint32_t>("the TSDF field size");
  const auto weight_bytes = r.get<uint32_t>("the weight field size");
  const auto color_bytes = r.get<uint32_t>("the colour field size");
  const auto tsdf_scale = r.get<float>("the TSDF scale");
  if (block_side != kBlockSide || tsdf_bytes != 2 || weight_bytes != 2 ||
      (color_bytes != 0 && color_bytes != 4) || tsdf_scale != kTsdfScale)
    fail(ErrorCode::Unsupported,
         "{}: voxel layout {}^3 blocks, TSDF {} B, weight {} B, colour {} B, scale {:g}; this "
         "hivox stores 8^3 blocks of 2 + 2 (+ 4) B, scale {:g}",
         what, block_side, tsdf_bytes, weight_bytes, color_bytes, tsdf_scale, kTsdfScale);
  m.store_color = color_bytes == 4;
  FusionParams& f = info.fusion;
  f.max_weight = r.get<int32_t>("the maximum weight");
  const auto sampling = r.get<uint32_t>("the depth sampling");
  if (sampling > 1) bad(fmt::format("unknown depth sampling {}", sampling));
  f.depth_sampling = sampling == 0 ? DepthSampling::Nearest : DepthSampling::Bilinear;
  f.depth_range.min_m = r.get<float>("the depth range");
  f.depth_range.max_m = r.get<float>("the depth range");
  f.integrate_color = r.get<uint32_t>("the colour flag") != 0;
  MapSession& s = info.session;
  s.frames_fused = r.get<int64_t>("the frame count");
  const auto flags = r.get<uint32_t>("the session flags");
  std::array<double, 12> pose{};
  for (double& v : pose) v = r.get<double>("the last pose");
  std::array<float, 4> k{};
  for (float& v : k) v = r.get<float>("the camera");
  const auto width = r.get<int32_t>("the camera");
  const auto height = r.get<int32_t>("the camera");
  try {
    m.validate();
    f.validate();
  } catch (const Error& e) {
    bad(e.what());
  }
  if (s.frames_fused < 0) bad(fmt::format("{} frames fused", s.frames_fused));
  if (flags & kHasPose) {
    Pose T = Pose::Identity();
    for (int row = 0; row < 3; ++row)
      for (int col = 0; col < 4; ++col)
        T.matrix()(row, col) = pose[static_cast<std::size_t>(row * 4 + col)];
    if (!T.matrix().allFinite()) bad("the last pose is not finite");
    s.last_pose = T;
  }
  if (flags & kHasCamera) {
    const PinholeCamera c{k[0], k[1], k[2], k[3], width, height};
    try {
      c.validate();
    } catch (const Error& e) {
      bad(fmt::format("camera: {}", e.what()));
    }
    s.camera = c;
  }
  for (int l = 0; l < m.levels; ++l) {
    LevelCounts c;
    c.blocks = r.get<int64_t>("the block counts");
    c.splits = r.get<int64_t>("the block counts");
    if (c.blocks < 0 || c.splits < 0 || c.blocks > (int64_t{1} << 31) ||
        c.splits > (int64_t{1} << 31))
      bad(fmt::format("level {}: {} blocks, {} split entries", l, c.blocks, c.splits));
    h.counts.push_back(c);
    info.blocks_per_level.push_back(c.blocks);
    info.splits_per_level.push_back(c.splits);
  }
  return h;
}

void check_counts_fit(const Header& h, const MapParams& capacity, const std::string& what) {
  int64_t blocks = 0;
  for (const LevelCounts& c : h.counts) blocks += c.blocks;
  if (blocks > capacity.max_blocks)
    fail(ErrorCode::OutOfCapacity,
         "{}: the map holds {} blocks, more than the voxel-block pool's {} (raise --max-blocks)",
         what, blocks, capacity.max_blocks);
  // Every split entry takes a hash entry: this bounds what their coordinates may take in memory.
  const int64_t entries = capacity.buckets_per_level + capacity.excess_per_level;
  for (std::size_t l = 0; l < h.counts.size(); ++l)
    if (h.counts[l].blocks + h.counts[l].splits > entries)
      fail(ErrorCode::OutOfCapacity,
           "{}: level {} holds {} blocks and split entries, more than its hash table's {} entries "
           "(raise --hash-buckets or --hash-excess)",
           what, l, h.counts[l].blocks + h.counts[l].splits, entries);
}

}  // namespace

void write_map_file(const fs::path& path, const VoxelBlockMap& map, const FusionParams& fusion,
                    const MapSession& session) {
  const MapParams& m = map.params();
  const bool color = m.store_color;
  std::vector<LevelContent> levels;
  std::vector<LevelCounts> counts;
  for (int l = 0; l < m.levels; ++l) {
    levels.push_back(level_content(map, l));
    counts.push_back({static_cast<int64_t>(levels.back().blocks.size()),
                      static_cast<int64_t>(levels.back().splits.size())});
  }
  // Every chunk of every level, compressed in parallel (each its own zstd frame: the same bytes
  // whatever the thread count).
  struct Job {
    int level;
    int64_t k;  ///< chunk of the level
  };
  std::vector<Job> jobs;
  for (int l = 0; l < m.levels; ++l)
    for (int64_t k = 0; k < counts[static_cast<std::size_t>(l)].chunks(); ++k)
      jobs.push_back({l, k});
  std::vector<std::vector<uint8_t>> chunks(jobs.size());
  std::vector<uint8_t> failed(jobs.size(), 0);
  parallel_for_dynamic(static_cast<int64_t>(jobs.size()), 1, [&](int64_t j) {
    const Job& job = jobs[static_cast<std::size_t>(j)];
    const LevelContent& level = levels[static_cast<std::size_t>(job.level)];
    const LevelCounts& c = counts[static_cast<std::size_t>(job.level)];
    const uint64_t raw_bytes = c.chunk_raw_bytes(job.k, color);
    thread_local std::vector<uint8_t> raw;
    const uint8_t* src = nullptr;
    if (job.k < c.index_chunks()) {
      src = level.index.data() + static_cast<uint64_t>(job.k) * kIndexChunkBytes;
    } else {
      const int64_t g = job.k - c.index_chunks();
      raw.resize(raw_bytes);
      fill_voxel_chunk(map, level.blocks.data() + g * kGroupBlocks, c.group_blocks(g), color,
                       raw.data());
      src = raw.data();
    }
    std::vector<uint8_t>& dst = chunks[static_cast<std::size_t>(j)];
    dst.resize(ZSTD_compressBound(raw_bytes));
    const std::size_t stored = ZSTD_compress(dst.data(), dst.size(), src, raw_bytes, kZstdLevel);
    if (ZSTD_isError(stored)) {  // out of memory: the bound always fits
      failed[static_cast<std::size_t>(j)] = 1;
      return;
    }
    dst.resize(stored);
  });
  if (std::find(failed.begin(), failed.end(), 1) != failed.end())
    fail(ErrorCode::Io, "{}: compression failed (out of memory?); nothing was written",
         path.string());

  Writer w;
  w.put_bytes(kMagic.data(), kMagic.size());
  w.put(kMapFileVersion);
  std::array<char, kVersionBytes> version{};
  const std::string_view v = library_version();
  std::memcpy(version.data(), v.data(), std::min(v.size(), kVersionBytes));
  w.put_bytes(version.data(), version.size());
  w.put(static_cast<uint32_t>(m.levels));
  w.put(m.voxel_size_m);
  w.put(m.truncation_m);
  w.put(static_cast<uint32_t>(kBlockSide));
  w.put(uint32_t{2});
  w.put(uint32_t{2});
  w.put(static_cast<uint32_t>(color ? 4 : 0));
  w.put(kTsdfScale);
  w.put(static_cast<int32_t>(fusion.max_weight));
  w.put(sampling_code(fusion.depth_sampling));
  w.put(fusion.depth_range.min_m);
  w.put(fusion.depth_range.max_m);
  w.put(static_cast<uint32_t>(fusion.integrate_color ? 1 : 0));
  w.put(session.frames_fused);
  w.put((session.last_pose ? kHasPose : 0u) | (session.camera ? kHasCamera : 0u));
  const Pose T = session.last_pose.value_or(Pose::Identity());
  for (int row = 0; row < 3; ++row)
    for (int col = 0; col < 4; ++col) w.put(T.matrix()(row, col));
  const PinholeCamera c = session.camera.value_or(PinholeCamera{});
  w.put(c.fx);
  w.put(c.fy);
  w.put(c.cx);
  w.put(c.cy);
  w.put(static_cast<int32_t>(session.camera ? c.width : 0));
  w.put(static_cast<int32_t>(session.camera ? c.height : 0));
  for (const LevelCounts& lc : counts) {
    w.put(lc.blocks);
    w.put(lc.splits);
  }
  for (const std::vector<uint8_t>& d : chunks) w.put(static_cast<uint32_t>(d.size()));
  // The checksum covers the header, the chunk table and every chunk.
  XXH3_state_t* state = XXH3_createState();
  XXH3_64bits_reset(state);
  XXH3_64bits_update(state, w.bytes().data(), w.bytes().size());
  for (const std::vector<uint8_t>& d : chunks) XXH3_64bits_update(state, d.data(), d.size());
  const uint64_t sum = XXH3_64bits_digest(state);
  XXH3_freeState(state);
  Writer trailer;
  trailer.put(sum);
  trailer.put_bytes(kEndMagic.data(), kEndMagic.size());

  std::vector<std::span<const uint8_t>> parts;
  parts.emplace_back(w.bytes());
  for (const std::vector<uint8_t>& d : chunks) parts.emplace_back(d);
  parts.emplace_back(trailer.bytes());
  write_file_atomically(path, parts);
}

namespace {

/// The whole file, checked (envelope) and its header parsed.
struct OpenedFile {
  std::string bytes;
  Header header;
  std::size_t table_at = 0;  ///< where the chunk table starts
};

OpenedFile open_map_file(const fs::path& path) {
  OpenedFile f;
  const std::string what = path.string();
  f.bytes = read_whole_file(path);
  const std::span<const uint8_t> all(reinterpret_cast<const uint8_t*>(f.bytes.data()),
                                     f.bytes.size());
  check_start(all, what);
  check_end(all, what);
  Reader r(all.first(all.size() - kTrailerBytes), what);
  f.header = parse_header(r, what, static_cast<int64_t>(all.size()));
  f.table_at = r.at();
  return f;
}

}  // namespace

bool is_map_file(const fs::path& path) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  std::array<char, kMagic.size()> head{};
  return f && std::fread(head.data(), 1, head.size(), f.get()) == head.size() && head == kMagic;
}

MapFileInfo read_map_file_info(const fs::path& path) {
  // The header only: it is a few hundred bytes at the start, and the whole file is checked when
  // the map is loaded.
  const std::string what = path.string();
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) fail(ErrorCode::Io, "{}: file does not exist", what);
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) fail(ErrorCode::Io, "{}: cannot open for reading", what);
  std::vector<uint8_t> head(1 << 16);
  head.resize(std::fread(head.data(), 1, head.size(), f.get()));
  check_start(head, what);
  Reader r(head, what);
  return parse_header(r, what, static_cast<int64_t>(fs::file_size(path, ec))).info;
}

LoadedMap read_map_file(const fs::path& path, const std::optional<MapParams>& capacities) {
  const std::string what = path.string();
  OpenedFile f = open_map_file(path);
  const Header& h = f.header;
  MapParams params = h.info.map;
  const bool color = params.store_color;
  int64_t total_blocks = 0;
  for (const LevelCounts& c : h.counts) total_blocks += c.blocks;
  if (capacities) {
    params.max_blocks = capacities->max_blocks;
    params.buckets_per_level = capacities->buckets_per_level;
    params.excess_per_level = capacities->excess_per_level;
  } else {
    // The defaults, raised to hold the file (a file holds content, not the writer's
    // capacities, so that the same content gives the same bytes).
    const MapParams defaults;
    int64_t per_level = 0;
    for (const LevelCounts& c : h.counts) per_level = std::max(per_level, c.blocks + c.splits);
    const int64_t cap = int64_t{1} << 28;
    params.max_blocks = std::max(defaults.max_blocks, total_blocks);
    params.buckets_per_level = std::max(
        defaults.buckets_per_level,
        static_cast<int64_t>(std::bit_ceil(static_cast<uint64_t>(std::min(per_level, cap)))));
    params.excess_per_level = std::max(defaults.excess_per_level, std::min(per_level, cap));
  }
  check_counts_fit(h, params, what);

  // The chunk table (stored sizes; raw sizes follow from the counts), then where each chunk is.
  const std::span<const uint8_t> all(reinterpret_cast<const uint8_t*>(f.bytes.data()),
                                     f.bytes.size());
  const std::size_t body_end = all.size() - kTrailerBytes;
  Reader table(all.first(body_end), what);
  table.get_bytes(f.table_at, "the header");
  std::vector<std::size_t> first_chunk(h.counts.size() + 1, 0);
  for (std::size_t l = 0; l < h.counts.size(); ++l)
    first_chunk[l + 1] = first_chunk[l] + static_cast<std::size_t>(h.counts[l].chunks());
  const std::size_t total_chunks = first_chunk.back();
  if (total_chunks > all.size() / 4)
    fail(ErrorCode::InvalidData, "{}: {} chunks do not fit in the file (corrupted)", what,
         total_chunks);
  std::vector<std::size_t> chunk_at(total_chunks), stored(total_chunks);
  for (std::size_t i = 0; i < total_chunks; ++i) stored[i] = table.get<uint32_t>("the chunk table");
  std::size_t at = table.at();
  for (std::size_t i = 0; i < total_chunks; ++i) {
    chunk_at[i] = at;
    if (stored[i] > body_end - at)
      fail(ErrorCode::InvalidData, "{}: chunk {} reaches past the end of the file (corrupted)",
           what, i);
    at += stored[i];
  }
  if (at != body_end)
    fail(ErrorCode::InvalidData, "{}: {} bytes after the last chunk (corrupted)", what,
         body_end - at);
  // Decompresses chunk k of level l into `out` (its raw size); false when it does not.
  auto decompress = [&](std::size_t l, int64_t k, uint8_t* out) {
    const std::size_t i = first_chunk[l] + static_cast<std::size_t>(k);
    const uint64_t raw = h.counts[l].chunk_raw_bytes(k, color);
    const std::size_t got = ZSTD_decompress(out, raw, all.data() + chunk_at[i], stored[i]);
    return !ZSTD_isError(got) && got == raw;
  };

  // The indexes: coordinates and update counts of every level.
  std::vector<BlockKey> keys, splits;
  std::vector<uint16_t> updates;
  std::vector<int64_t> level_start(h.counts.size() + 1, 0);  // first key of each level
  for (std::size_t l = 0; l < h.counts.size(); ++l) {
    const LevelCounts& c = h.counts[l];
    std::vector<uint8_t> index(c.index_bytes());
    std::vector<uint8_t> ok(static_cast<std::size_t>(c.index_chunks()), 0);
    parallel_for(c.index_chunks(), [&](int64_t k) {
      ok[static_cast<std::size_t>(k)] =
          decompress(l, k, index.data() + static_cast<uint64_t>(k) * kIndexChunkBytes);
    });
    if (std::find(ok.begin(), ok.end(), 0) != ok.end())
      fail(ErrorCode::InvalidData, "{}: the index of level {} does not decompress (corrupted)",
           what, l);
    auto key_at = [&](int64_t i) {
      int32_t xyz[3];
      std::memcpy(xyz, index.data() + 12 * i, sizeof xyz);
      return BlockKey{{xyz[0], xyz[1], xyz[2]}, static_cast<int32_t>(l)};
    };
    for (int64_t i = 0; i < c.splits; ++i) splits.push_back(key_at(i));
    for (int64_t i = 0; i < c.blocks; ++i) keys.push_back(key_at(c.splits + i));
    const uint8_t* u = index.data() + 12 * (c.splits + c.blocks);
    for (int64_t i = 0; i < c.blocks; ++i) {
      uint16_t v = 0;
      std::memcpy(&v, u + 2 * i, 2);
      updates.push_back(v);
    }
    level_start[l + 1] = level_start[l] + c.blocks;
  }

  // The voxels go from each chunk straight into the map: the restore fills contiguous runs of
  // blocks per thread, so each thread decompresses a chunk once into its own buffer.
  static std::atomic<uint64_t> loads{0};
  const uint64_t load = ++loads;
  std::atomic<bool> damaged{false};
  auto map = std::make_unique<VoxelBlockMap>(params);
  restore_blocks(
      *map, keys, splits,
      [&](std::size_t i, TsdfVoxel* tsdf, ColorVoxel* rgb, uint16_t* block_updates) {
        struct Cache {
          uint64_t load = 0;
          std::size_t level = 0;
          int64_t group = -1;
          bool ok = false;
          std::vector<uint8_t> raw;
        };
        thread_local Cache cache;
        const auto b = static_cast<int64_t>(i);
        const auto l = static_cast<std::size_t>(
            std::upper_bound(level_start.begin(), level_start.end(), b) - level_start.begin() - 1);
        const LevelCounts& c = h.counts[l];
        const int64_t j = b - level_start[l];
        const int64_t g = j / kGroupBlocks;
        if (cache.load != load || cache.level != l || cache.group != g) {
          cache = {load, l, g, false, std::move(cache.raw)};
          cache.raw.resize(c.chunk_raw_bytes(c.index_chunks() + g, color));
          cache.ok = decompress(l, c.index_chunks() + g, cache.raw.data());
          if (!cache.ok) damaged = true;
        }
        *block_updates = updates[i];
        if (cache.ok)
          read_voxel_chunk(cache.raw.data(), c.group_blocks(g), j % kGroupBlocks, color, tsdf, rgb);
      },
      what);
  if (damaged)
    fail(ErrorCode::InvalidData, "{}: a voxel chunk does not decompress to its size (corrupted)",
         what);
  return {std::move(map), h.info};
}

void check_map_continues(const MapFileInfo& info, const fs::path& path, const MapParams& map,
                         const FusionParams& fusion) {
  const std::string diff = info.map.shape_difference(map);
  if (!diff.empty())
    fail(ErrorCode::InvalidArgument,
         "{}: the map was made with other settings than this run's ({}, the file's first): a map "
         "continues only with its own (leave the option out to take the file's)",
         path.string(), diff);
  if (info.fusion.max_weight != fusion.max_weight)
    fail(ErrorCode::InvalidArgument,
         "{}: the map was fused with maximum weight {}, this run asks for {} (leave --max-weight "
         "out to take the file's)",
         path.string(), info.fusion.max_weight, fusion.max_weight);
}

}  // namespace hivox

// Map files: exact round trips, continuing a saved map bit for bit, and every kind of damaged,
// foreign or contradicting file refused with an error that names it.

#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <map>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#define XXH_INLINE_ALL
#include <xxhash.h>

#include "hivox/io/atomic_file.h"
#include "hivox/io/dataset.h"
#include "hivox/io/map_file.h"
#include "hivox/map/hierarchy_edit.h"
#include "hivox/map/stored_map.h"
#include "hivox/mesh/extract_mesh.h"
#include "hivox/run/runner.h"
#include "hivox/synth/synthetic_dataset.h"
#include "map/map_access.h"
#include "map/map_invariants.h"
#include "test_util.h"

namespace hivox {
namespace {

namespace fs = std::filesystem;

std::string bytes_of(const fs::path& p) {
  return read_whole_file(p);
}

void write_bytes(const fs::path& p, const std::string& bytes) {
  std::ofstream(p, std::ios::binary)
      .write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

/// Everything a reader of the map sees, by key: voxels (TSDF and weight), colours, update
/// counts, surface summaries; and the Split entries.
struct Content {
  std::map<std::tuple<int, int, int, int>, std::vector<uint32_t>> voxels, colors;
  std::map<std::tuple<int, int, int, int>, std::tuple<int, int, int>> meta;
  std::vector<std::tuple<int, int, int, int>> splits;
  bool operator==(const Content&) const = default;
};

Content content_of(const VoxelBlockMap& map) {
  Content c;
  for (const BlockRef& b : map.allocated_blocks()) {
    const auto key = std::make_tuple(b.level, b.pos.x, b.pos.y, b.pos.z);
    std::vector<uint32_t> v(kBlockVoxels), col;
    std::memcpy(v.data(), map.block_tsdf(b.ptr), sizeof(TsdfVoxel) * kBlockVoxels);
    c.voxels[key] = v;
    if (map.block_color(b.ptr)) {
      col.resize(kBlockVoxels);
      std::memcpy(col.data(), map.block_color(b.ptr), sizeof(ColorVoxel) * kBlockVoxels);
      c.colors[key] = col;
    }
    const BlockMeta& m = map.block_meta(b.ptr);
    c.meta[key] = {m.updates, m.surface.observed, m.surface.surface};
  }
  for (int l = 0; l < map.levels(); ++l)
    for (const Vec3i& p : sorted_split_entries(map, l)) c.splits.emplace_back(l, p.x, p.y, p.z);
  return c;
}

/// A small multi-level map fused from a synthetic scene (splits and merges included).
RunResult small_run(std::size_t frames, std::size_t first = 0, const fs::path& map_in = {}) {
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=40&noise=kinect"));
  RunParams p;
  p.poses.source = PoseSource::GroundTruth;
  p.first_frame = first;
  p.max_frames = frames;
  p.map_in = map_in;
  p.reconstruction.map.voxel_size_m = 0.008f;
  p.reconstruction.map.truncation_m = 0.064f;
  p.reconstruction.map.max_blocks = 1 << 16;
  p.reconstruction.map.buckets_per_level = 1 << 14;
  p.reconstruction.map.excess_per_level = 1 << 14;
  p.reconstruction.refine.every_n_frames = 2;
  p.reconstruction.refine.min_updates = 1;
  return run_reconstruction(data, p);
}

TEST(MapFile, SaveLoadSaveGivesTheSameBytesAndTheSameMap) {
  test::TempDir dir;
  const RunResult run = small_run(6);
  const VoxelBlockMap& map = run.reconstruction->map();
  ASSERT_GT(map.blocks_in_use(), 500);
  int64_t splits = 0;
  for (const int64_t n : map.split_entries_per_level()) splits += n;
  ASSERT_GT(splits, 0) << "the test needs a map with split regions";
  const MapSession session = run.reconstruction->session();
  EXPECT_EQ(session.frames_fused, 6);
  write_map_file(dir / "a.hvx", map, run.reconstruction->params().fusion, session);

  const LoadedMap loaded = read_map_file(dir / "a.hvx");
  test::expect_map_consistent(*loaded.map);
  EXPECT_TRUE(content_of(*loaded.map) == content_of(map));
  EXPECT_EQ(loaded.info.session.frames_fused, 6);
  ASSERT_TRUE(loaded.info.session.last_pose.has_value());
  EXPECT_TRUE(loaded.info.session.last_pose->matrix() == session.last_pose->matrix());
  ASSERT_TRUE(loaded.info.session.camera.has_value());
  EXPECT_EQ(loaded.info.session.camera->width, session.camera->width);
  EXPECT_EQ(loaded.info.map.shape_difference(map.params()), "");
  EXPECT_EQ(loaded.info.fusion.max_weight, run.reconstruction->params().fusion.max_weight);
  EXPECT_EQ(loaded.info.blocks_per_level, map.blocks_per_level());

  write_map_file(dir / "b.hvx", *loaded.map, loaded.info.fusion, loaded.info.session);
  EXPECT_TRUE(bytes_of(dir / "a.hvx") == bytes_of(dir / "b.hvx"));

  // The mesh of the loaded map is the mesh of the map that was saved.
  const TriangleMesh m1 = extract_mesh(map), m2 = extract_mesh(*loaded.map);
  EXPECT_GT(m1.triangle_count(), 1000);
  EXPECT_TRUE(m1.positions_w == m2.positions_w);
  EXPECT_TRUE(m1.triangles == m2.triangles);
  EXPECT_TRUE(m1.colors == m2.colors);
}

// Stopping after half the frames, saving, loading and fusing the rest gives the map of the
// uninterrupted run, byte for byte (the refinement's cadence and every block's update count
// carry over).
TEST(MapFile, ContinuingASavedMapEqualsNeverStopping) {
  test::TempDir dir;
  const RunResult whole = small_run(10);
  write_map_file(dir / "whole.hvx", whole.reconstruction->map(),
                 whole.reconstruction->params().fusion, whole.reconstruction->session());
  for (const std::size_t half : {std::size_t{4}, std::size_t{5}}) {  // both refinement phases
    const RunResult first = small_run(half);
    write_map_file(dir / "first.hvx", first.reconstruction->map(),
                   first.reconstruction->params().fusion, first.reconstruction->session());
    const RunResult rest = small_run(10 - half, half, dir / "first.hvx");
    EXPECT_EQ(rest.reconstruction->session().frames_fused, 10);
    EXPECT_TRUE(content_of(rest.reconstruction->map()) == content_of(whole.reconstruction->map()))
        << "split after " << half << " frames";
    write_map_file(dir / "rest.hvx", rest.reconstruction->map(),
                   rest.reconstruction->params().fusion, rest.reconstruction->session());
    EXPECT_TRUE(bytes_of(dir / "rest.hvx") == bytes_of(dir / "whole.hvx"))
        << "split after " << half << " frames";
  }
}

// The same on a real sequence through the library's run (ground-truth poses): 40 frames of
// fr1/rpy in one run, or 20 + 20 with the map saved and loaded between.
TEST(MapFile, ContinuingARealSequenceEqualsNeverStopping) {
  HIVOX_REQUIRE_DATASET(data, "tum_fr1_rpy");
  test::TempDir dir;
  auto run = [&](std::size_t first, std::size_t frames, const fs::path& in, const fs::path& out) {
    const auto reader = open_dataset(data.string(), DatasetParams{});
    RunParams p;
    p.poses.source = PoseSource::GroundTruth;
    p.first_frame = first;
    p.max_frames = frames;
    p.map_in = in;
    p.map_out = out;
    p.reconstruction.raycast_every_frame = false;
    return run_reconstruction(*reader, p);
  };
  const RunResult whole = run(0, 40, {}, dir / "whole.hvx");
  run(0, 20, {}, dir / "first.hvx");
  const RunResult rest = run(20, 20, dir / "first.hvx", dir / "rest.hvx");
  EXPECT_GT(whole.reconstruction->map().blocks_in_use(), 20000);
  EXPECT_TRUE(bytes_of(dir / "rest.hvx") == bytes_of(dir / "whole.hvx"));
  const TriangleMesh a = extract_mesh(whole.reconstruction->map());
  const TriangleMesh b = extract_mesh(rest.reconstruction->map());
  EXPECT_TRUE(a.positions_w == b.positions_w && a.triangles == b.triangles);
}

/// A map file of a few blocks at two levels with one split region, for the damage tests.
fs::path tiny_map_file(const test::TempDir& dir) {
  MapParams p;
  p.voxel_size_m = 0.01f;
  p.levels = 2;
  p.truncation_m = 0.04f;
  p.max_blocks = 64;
  p.buckets_per_level = 64;
  p.excess_per_level = 64;
  VoxelBlockMap map(p);
  std::vector<BlockKey> keys = {{{0, 0, 0}, 1}, {{1, 0, 0}, 1}, {{-1, 2, 3}, 1}};
  std::vector<BlockRef> refs;
  map.insert_blocks(keys, &refs);
  for (const BlockRef& b : refs) {
    TsdfVoxel* v = MapAccess::tsdf(map, b.ptr);
    ColorVoxel* c = MapAccess::color(map, b.ptr);
    for (int i = 0; i < kBlockVoxels; ++i) {
      v[i] = {static_cast<int16_t>(1000 * (voxel_coords(i).z - 4)), static_cast<uint16_t>(5)};
      c[i] = {static_cast<uint8_t>(i), 7, 9, 5};
    }
    MapAccess::meta(map, b.ptr).updates = 3;
    MapAccess::refresh_surface(map, b.ptr);
  }
  const std::vector<BlockRef> to_split = {refs[0]};
  EXPECT_EQ(split_blocks(map, to_split).done, 1);
  MapSession s;
  s.frames_fused = 12;
  write_map_file(dir / "tiny.hvx", map, FusionParams{}, s);
  return dir / "tiny.hvx";
}

/// The error of loading `path`, checking it names the file; no map may come back.
Error load_error(const fs::path& path) {
  const Error e = test::error_of([&] { read_map_file(path); });
  EXPECT_TRUE(test::contains(e.what(), path.string())) << e.what();
  return e;
}

// Every single byte changed, anywhere (header, chunk table, voxels, checksum, end marker), is
// refused with one clear error; so is every truncation.
TEST(MapFile, EveryDamagedByteAndEveryTruncationIsRefused) {
  test::TempDir dir;
  const fs::path good = tiny_map_file(dir);
  const std::string bytes = bytes_of(good);
  ASSERT_GT(bytes.size(), 300u);
  const LoadedMap ok = read_map_file(good);
  EXPECT_EQ(ok.map->blocks_in_use(), 2 + 8);
  const fs::path bad = dir / "bad.hvx";
  std::map<std::string, int> messages;
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    std::string b = bytes;
    b[i] = static_cast<char>(b[i] ^ (1 << (i % 8)));
    write_bytes(bad, b);
    const Error e = load_error(bad);
    EXPECT_TRUE(e.code() == ErrorCode::InvalidData || e.code() == ErrorCode::Unsupported)
        << "byte " << i << ": " << e.what();
    const std::string what = e.what();
    messages[what.substr(what.find(": ") + 2, 24)]++;
  }
  // Which check caught them: the magic, the version, the checksum and the end marker.
  EXPECT_GE(messages.size(), 4u);
  for (std::size_t n = 0; n < bytes.size(); n += 7) {
    write_bytes(bad, bytes.substr(0, n));
    const Error e = load_error(bad);
    EXPECT_EQ(e.code(), ErrorCode::InvalidData) << "cut at " << n << ": " << e.what();
  }
  write_bytes(bad, bytes + "x");
  EXPECT_TRUE(test::contains(load_error(bad).what(), "end marker"));
}

/// `bytes` with its checksum recomputed: a file damaged by someone who also fixed the checksum,
/// which the checks behind the checksum must still refuse.
std::string with_checksum(std::string bytes) {
  const std::size_t body = bytes.size() - 16;
  const uint64_t sum = XXH3_64bits(bytes.data(), body);
  std::memcpy(bytes.data() + body, &sum, 8);
  return bytes;
}

// The header alone is read from the start of the file (cheap for any map): a damaged body does
// not stop it, loading the map does.
TEST(MapFile, TheHeaderIsReadAloneTheBodyWhenLoading) {
  test::TempDir dir;
  const fs::path good = tiny_map_file(dir);
  std::string bytes = bytes_of(good);
  bytes[bytes.size() - 20] = static_cast<char>(bytes[bytes.size() - 20] ^ 1);  // in a chunk
  const fs::path bad = dir / "bad.hvx";
  write_bytes(bad, bytes);
  const MapFileInfo info = read_map_file_info(bad);
  EXPECT_EQ(info.blocks_per_level, read_map_file_info(good).blocks_per_level);
  EXPECT_EQ(info.session.frames_fused, 12);
  EXPECT_EQ(info.file_bytes, static_cast<int64_t>(bytes.size()));
  EXPECT_TRUE(test::contains(load_error(bad).what(), "checksum mismatch"));
  write_bytes(bad, bytes.substr(0, 40));
  EXPECT_TRUE(test::contains(test::error_of([&] { read_map_file_info(bad); }).what(),
                             "the header ends inside"));
}

TEST(MapFile, ContentBehindAValidChecksumIsCheckedToo) {
  test::TempDir dir;
  const std::string bytes = bytes_of(tiny_map_file(dir));
  const fs::path bad = dir / "bad.hvx";
  // A format version from the future.
  std::string b = bytes;
  b[8] = 2;
  write_bytes(bad, with_checksum(b));
  Error e = load_error(bad);
  EXPECT_EQ(e.code(), ErrorCode::Unsupported);
  EXPECT_TRUE(test::contains(e.what(), "newer")) << e.what();
  // Every byte before the checksum changed (header, chunk table, index, voxels), the checksum
  // fixed: an error naming the file or a consistent map, never a crash.
  int refused = 0;
  std::map<std::string, int> caught_by;
  MapParams small;
  small.max_blocks = 64;
  small.buckets_per_level = 64;
  small.excess_per_level = 64;
  for (std::size_t i = 12; i + 16 < bytes.size(); ++i) {
    b = bytes;
    b[i] = static_cast<char>(b[i] ^ 0x5a);
    write_bytes(bad, with_checksum(b));
    try {
      const LoadedMap m = read_map_file(bad, small);
      test::expect_map_consistent(*m.map);
    } catch (const Error& err) {
      ++refused;
      EXPECT_TRUE(test::contains(err.what(), bad.string())) << err.what();
      const std::string w = err.what();
      for (const char* check : {"voxel chunk", "index of level", "stored twice", "chunk"})
        if (test::contains(w, check)) {
          ++caught_by[check];
          break;
        }
    }
  }
  EXPECT_GT(refused, 100);
  EXPECT_GT(caught_by["voxel chunk"], 0) << "damaged voxels behind a valid checksum";
  EXPECT_GT(caught_by["index of level"], 0) << "a damaged index behind a valid checksum";
}

TEST(MapFile, ForeignMissingAndContradictingFilesGiveClearErrors) {
  test::TempDir dir;
  Error e = load_error(dir / "missing.hvx");
  EXPECT_EQ(e.code(), ErrorCode::Io);
  test::write_text(dir / "mesh.ply", "ply\nformat ascii 1.0\nend_header\n");
  e = load_error(dir / "mesh.ply");
  EXPECT_TRUE(test::contains(e.what(), "not a hivox map file")) << e.what();
  EXPECT_FALSE(is_map_file(dir / "mesh.ply"));

  const fs::path good = tiny_map_file(dir);
  EXPECT_TRUE(is_map_file(good));
  const MapFileInfo info = read_map_file_info(good);
  MapParams m = info.map;
  FusionParams f = info.fusion;
  check_map_continues(info, good, m, f);  // its own settings continue it
  m.voxel_size_m = 0.005f;
  e = test::error_of([&] { check_map_continues(info, good, m, f); });
  EXPECT_EQ(e.code(), ErrorCode::InvalidArgument);
  EXPECT_TRUE(test::contains(e.what(), "voxel size")) << e.what();
  EXPECT_TRUE(test::contains(e.what(), good.string())) << e.what();
  m = info.map;
  m.store_color = false;
  EXPECT_TRUE(test::contains(test::error_of([&] { check_map_continues(info, good, m, f); }).what(),
                             "colour"));
  m = info.map;
  f.max_weight = 7;
  EXPECT_TRUE(test::contains(test::error_of([&] { check_map_continues(info, good, m, f); }).what(),
                             "maximum weight"));

  // Capacities too small for the file: named, nothing half-loaded.
  MapParams small = info.map;
  small.max_blocks = 4;
  e = test::error_of([&] { read_map_file(good, small); });
  EXPECT_EQ(e.code(), ErrorCode::OutOfCapacity);
  EXPECT_TRUE(test::contains(e.what(), "--max-blocks")) << e.what();
}

// The map's own checks on restored content: the hierarchy's invariants hold or nothing loads.
TEST(StoredMap, RestoreRefusesContentThatIsNoValidHierarchy) {
  MapParams p;
  p.levels = 3;
  p.max_blocks = 128;
  p.buckets_per_level = 64;
  p.excess_per_level = 64;
  auto nothing = [](std::size_t, TsdfVoxel*, ColorVoxel*, uint16_t*) {};
  auto refuse = [&](std::vector<BlockKey> blocks, std::vector<BlockKey> splits,
                    const std::string& why) {
    VoxelBlockMap map(p);
    const Error e = test::error_of([&] { restore_blocks(map, blocks, splits, nothing, "f.hvx"); });
    EXPECT_EQ(e.code(), ErrorCode::InvalidData) << e.what();
    EXPECT_TRUE(test::contains(e.what(), "f.hvx: ")) << e.what();
    EXPECT_TRUE(test::contains(e.what(), why)) << e.what();
    EXPECT_EQ(map.blocks_in_use(), 0);
  };
  std::vector<BlockKey> children;
  for (int c = 0; c < kBlockChildren; ++c) children.push_back({child_block_pos({1, 2, 3}, c), 0});
  refuse({{{0, 0, 0}, 0}, {{0, 0, 0}, 0}}, {}, "stored twice");
  refuse({{{0, 0, 0}, 3}}, {}, "3 level(s)");
  refuse({{{kMaxStoredBlockCoord + 1, 0, 0}, 0}}, {}, "coordinate");
  refuse({}, {{{0, 0, 0}, 0}}, "finest level");
  refuse(std::vector<BlockKey>(children.begin(), children.end() - 1), {{{1, 2, 3}, 1}},
         "is missing");
  std::vector<BlockKey> twice = children;
  twice.push_back({{1, 2, 3}, 1});
  refuse(twice, {}, "stored twice");
  twice = children;
  twice.push_back({{0, 1, 1}, 2});  // the grandparent region, stored as a block as well
  refuse(twice, {}, "inside the block");

  // The valid version of the same loads, with every block filled by the callback.
  VoxelBlockMap map(p);
  children.push_back({{5, 5, 5}, 2});
  restore_blocks(
      map, children, std::vector<BlockKey>{{{1, 2, 3}, 1}},
      [](std::size_t i, TsdfVoxel* v, ColorVoxel*, uint16_t* updates) {
        v[0] = {-5, static_cast<uint16_t>(i + 1)};
        *updates = static_cast<uint16_t>(i);
      },
      "f.hvx");
  test::expect_map_consistent(map);
  EXPECT_EQ(map.blocks_in_use(), 9);
  EXPECT_EQ(map.split_entries_per_level()[1], 1);
  const auto b = map.find(2, {5, 5, 5});
  ASSERT_TRUE(b.has_value());
  EXPECT_EQ(map.block_tsdf(b->ptr)[0].weight, 9);
  EXPECT_EQ(map.block_meta(b->ptr).updates, 8);
  EXPECT_EQ(map.block_meta(b->ptr).surface.surface, 1);
  // Restoring into a map that holds blocks is refused.
  EXPECT_EQ(test::error_of([&] { restore_blocks(map, children, {}, nothing, "f.hvx"); }).code(),
            ErrorCode::InvalidArgument);
}

}  // namespace
}  // namespace hivox

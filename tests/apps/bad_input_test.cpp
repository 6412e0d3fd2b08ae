// Broken input, case by case, through the `hivox` program: datasets, calibrations, trajectories,
// images, synthetic specs and flags. Each case builds its input from a small sequence the test
// exports itself (or a built-in scene), runs hivox, and states the exit status and what the one
// line must name. Nothing may crash, hang or exit 0 without a result.

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "apps/cli_util.h"
#include "hivox/core/image.h"
#include "hivox/io/image_io.h"
#include "test_util.h"

namespace hivox {
namespace {

namespace fs = std::filesystem;
using test::run_hivox;

/// Exit status of a command-line mistake (CLI11's own codes, all >= 100).
constexpr int kUsage = -100;

struct Case {
  const char* name;
  /// Prepares the input in `dir` (holding `seq`, a copy of a 4-frame TUM sequence) and returns
  /// hivox's arguments.
  std::function<std::string(const fs::path& dir)> setup;
  int exit_code;                      ///< kUsage: any CLI11 code
  std::vector<std::string> expected;  ///< parts of the output
};

// ---- helpers that break files --------------------------------------------------------------

void write(const fs::path& p, const std::string& text) {
  std::ofstream(p, std::ios::binary) << text;
}

std::string read(const fs::path& p) {
  return test::file_bytes(p);
}

/// Replaces the first `from` in file `p` by `to`.
void replace_in(const fs::path& p, const std::string& from, const std::string& to) {
  std::string s = read(p);
  const auto at = s.find(from);
  ASSERT_NE(at, std::string::npos) << from << " in " << p;
  s.replace(at, from.size(), to);
  write(p, s);
}

/// The depth (or colour) images of the sequence, in time order.
std::vector<fs::path> images(const fs::path& dir) {
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(dir)) out.push_back(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

uint32_t crc32(const uint8_t* data, std::size_t n) {
  uint32_t c = 0xFFFFFFFFu;
  for (std::size_t i = 0; i < n; ++i) {
    c ^= data[i];
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
  }
  return ~c;
}

/// A PNG whose header (with a valid checksum) claims `width` x `height` pixels.
void write_png_claiming(const fs::path& p, uint32_t width, uint32_t height) {
  Image<uint16_t> one(1, 1, uint16_t{1000});
  write_png(p, one);
  std::string s = read(p);
  auto put = [&](std::size_t at, uint32_t v) {
    for (int k = 0; k < 4; ++k) s[at + k] = static_cast<char>((v >> (24 - 8 * k)) & 0xFF);
  };
  put(16, width);  // IHDR data starts at 16: width, height
  put(20, height);
  put(29, crc32(reinterpret_cast<const uint8_t*>(s.data()) + 12, 17));  // over type + data
  write(p, s);
}

std::string reconstruct(const fs::path& dir, const std::string& extra,
                        const std::string& dataset = "") {
  return "reconstruct " + (dataset.empty() ? (dir / "seq").string() : dataset) +
         " --levels 1 --voxel-size 0.01 --truncation 0.04 --quiet --out " + (dir / "out").string() +
         " " + extra;
}

const std::string kScene = "'synthetic:box?frames=3&width=80&height=60&noise=none'";

std::vector<Case> cases() {
  std::vector<Case> c;
  // Datasets.
  c.push_back({"missing folder",
               [](const fs::path& d) { return reconstruct(d, "", "/no/such/set"); },
               1,
               {"/no/such/set"}});
  c.push_back({"folder of nothing known",
               [](const fs::path& d) {
                 fs::create_directories(d / "empty");
                 write(d / "empty" / "readme.txt", "hello");
                 return reconstruct(d, "", (d / "empty").string());
               },
               1,
               {"empty", "associations.txt"}});
  c.push_back({"association line cut short",
               [](const fs::path& d) {
                 replace_in(d / "seq" / "associations.txt", "0.033333 rgb/0.033333.png 0.033333",
                            "0.033333 rgb/0.033333.png");
                 return reconstruct(d, "--poses gt");
               },
               1,
               {"associations.txt"}});
  c.push_back({"associated depth file missing",
               [](const fs::path& d) {
                 fs::remove(images(d / "seq" / "depth")[0]);
                 return reconstruct(d, "--poses gt");
               },
               1,
               {"0.000000.png"}});
  c.push_back({"non-numeric timestamp",
               [](const fs::path& d) {
                 replace_in(d / "seq" / "associations.txt", "0.066667 rgb", "0.0x6667 rgb");
                 return reconstruct(d, "--poses gt");
               },
               1,
               {"associations.txt", "0.0x6667"}});
  c.push_back({"no frames listed",
               [](const fs::path& d) {
                 write(d / "seq" / "associations.txt", "# nothing\n");
                 return reconstruct(d, "--poses gt");
               },
               1,
               {"associations.txt"}});
  c.push_back({"first depth image truncated",
               [](const fs::path& d) {
                 const fs::path p = images(d / "seq" / "depth")[0];
                 fs::resize_file(p, fs::file_size(p) / 2);
                 return reconstruct(d, "--poses gt");
               },
               1,
               {"0.000000.png"}});
  c.push_back({"depth image not a PNG",
               [](const fs::path& d) {
                 write(images(d / "seq" / "depth")[0], "this is text");
                 return reconstruct(d, "--poses gt");
               },
               1,
               {"0.000000.png"}});
  c.push_back({"depth image is colour",
               [](const fs::path& d) {
                 write_png(images(d / "seq" / "depth")[0], ColorImage(80, 60, Rgb8{1, 2, 3}));
                 return reconstruct(d, "--poses gt");
               },
               1,
               {"0.000000.png", "16-bit"}});
  c.push_back({"depth image of another size",
               [](const fs::path& d) {
                 write_png(images(d / "seq" / "depth")[0], Image<uint16_t>(40, 30, uint16_t{5000}));
                 return reconstruct(d, "--poses gt");
               },
               1,
               {"40x30"}});
  c.push_back({"depth header claiming 100000x100000",
               [](const fs::path& d) {
                 write_png_claiming(images(d / "seq" / "depth")[0], 100000, 100000);
                 return reconstruct(d, "--poses gt");
               },
               1,
               {"0.000000.png", "100000x100000"}});
  c.push_back({"later depth image truncated: stop",
               [](const fs::path& d) {
                 const fs::path p = images(d / "seq" / "depth")[2];
                 fs::resize_file(p, fs::file_size(p) / 3);
                 return reconstruct(d, "--poses gt");
               },
               4,
               {"0.066667.png", "--on-bad-frame"}});
  c.push_back({"later depth image truncated: skip",
               [](const fs::path& d) {
                 const fs::path p = images(d / "seq" / "depth")[2];
                 fs::resize_file(p, fs::file_size(p) / 3);
                 return reconstruct(d, "--poses gt --on-bad-frame skip");
               },
               0,
               {"0.066667.png", "skipped"}});
  c.push_back({"colour image missing",
               [](const fs::path& d) {
                 fs::remove(images(d / "seq" / "rgb")[0]);
                 return reconstruct(d, "--poses gt");
               },
               1,
               {"0.000000.png"}});
  c.push_back({"colour image corrupt",
               [](const fs::path& d) {
                 const fs::path p = images(d / "seq" / "rgb")[0];
                 fs::resize_file(p, 60);
                 return reconstruct(d, "--poses gt");
               },
               1,
               {"0.000000.png"}});
  c.push_back({"timestamps out of order",
               [](const fs::path& d) {
                 replace_in(d / "seq" / "associations.txt",
                            "0.033333 rgb/0.033333.png 0.033333 depth/0.033333.png\n"
                            "0.066667 rgb/0.066667.png 0.066667 depth/0.066667.png",
                            "0.066667 rgb/0.066667.png 0.066667 depth/0.066667.png\n"
                            "0.033333 rgb/0.033333.png 0.033333 depth/0.033333.png");
                 return reconstruct(d, "--poses gt");
               },
               0,
               {"out of order"}});
  c.push_back({"timestamps duplicated",
               [](const fs::path& d) {
                 replace_in(d / "seq" / "associations.txt", "0.033333 rgb/0.033333.png 0.033333",
                            "0.000000 rgb/0.033333.png 0.000000");
                 return reconstruct(d, "--poses gt");
               },
               0,
               {"duplicated"}});
  // Ground truth and trajectories.
  c.push_back({"ground truth line malformed",
               [](const fs::path& d) {
                 replace_in(d / "seq" / "groundtruth.txt", "0.033333 0.5", "0.033333 zero.5");
                 return reconstruct(d, "--poses gt");
               },
               1,
               {"groundtruth.txt"}});
  c.push_back({"--poses gt without ground truth",
               [](const fs::path& d) {
                 fs::remove(d / "seq" / "groundtruth.txt");
                 return reconstruct(d, "--poses gt");
               },
               1,
               {"ground-truth", "--poses FILE"}});
  c.push_back(
      {"pose file missing",
       [](const fs::path& d) { return reconstruct(d, "--poses " + (d / "nope.txt").string()); },
       1,
       {"nope.txt"}});
  c.push_back({"pose file malformed",
               [](const fs::path& d) {
                 write(d / "poses.txt", "0.0 1 2 3 0 0 0\n");
                 return reconstruct(d, "--poses " + (d / "poses.txt").string());
               },
               1,
               {"poses.txt"}});
  c.push_back({"pose file empty",
               [](const fs::path& d) {
                 write(d / "poses.txt", "# nothing\n");
                 return reconstruct(d, "--poses " + (d / "poses.txt").string());
               },
               1,
               {"poses.txt", "no poses"}});
  c.push_back({"pose file with a zero quaternion",
               [](const fs::path& d) {
                 write(d / "poses.txt", "0.0 1 2 3 0 0 0 0\n");
                 return reconstruct(d, "--poses " + (d / "poses.txt").string());
               },
               1,
               {"poses.txt"}});
  c.push_back({"pose file with nan",
               [](const fs::path& d) {
                 write(d / "poses.txt", "0.0 nan 2 3 0 0 0 1\n");
                 return reconstruct(d, "--poses " + (d / "poses.txt").string());
               },
               1,
               {"poses.txt"}});
  c.push_back({"pose file timestamps duplicated",
               [](const fs::path& d) {
                 std::string gt = read(d / "seq" / "groundtruth.txt");
                 write(d / "poses.txt", gt + gt.substr(gt.find("\n0.000000") + 1));
                 return reconstruct(d, "--poses " + (d / "poses.txt").string());
               },
               0,
               {"poses.txt", "duplicated"}});
  c.push_back({"pose file covering no frame",
               [](const fs::path& d) {
                 write(d / "poses.txt", "100.0 0 0 0 0 0 0 1\n");
                 return reconstruct(d, "--poses " + (d / "poses.txt").string());
               },
               1,
               {"no frame could be integrated"}});
  // Calibration files.
  c.push_back({"intrinsics not JSON",
               [](const fs::path& d) {
                 write(d / "seq" / "intrinsics.json", "{ fx: ");
                 return reconstruct(d, "--poses gt");
               },
               1,
               {"intrinsics.json", "JSON"}});
  // The base sequence's intrinsics.json with `from` replaced by `to`, run with its poses.
  const auto intrinsics_edit = [](const char* name, std::string from, std::string to,
                                  std::vector<std::string> expected) {
    return Case{name,
                [from, to](const fs::path& d) {
                  replace_in(d / "seq" / "intrinsics.json", from, to);
                  return reconstruct(d, "--poses gt");
                },
                1, std::move(expected)};
  };
  c.push_back(
      intrinsics_edit("intrinsics without fx", "\"fx\"", "\"f_x\"", {"intrinsics.json", "fx"}));
  c.push_back(intrinsics_edit("intrinsics fx negative", "\"fx\": 65.625", "\"fx\": -65.625",
                              {"intrinsics.json", "fx"}));
  c.push_back(intrinsics_edit("intrinsics fx a string", "\"fx\": 65.625", "\"fx\": \"big\"",
                              {"intrinsics.json", "fx"}));
  c.push_back(intrinsics_edit("intrinsics width 1e9", "\"width\": 80", "\"width\": 1e9",
                              {"intrinsics.json", "width"}));
  c.push_back(intrinsics_edit("intrinsics width 1e30", "\"width\": 80", "\"width\": 1e30",
                              {"intrinsics.json", "width"}));
  c.push_back(intrinsics_edit("intrinsics width fractional", "\"width\": 80", "\"width\": 80.5",
                              {"intrinsics.json", "integer"}));
  c.push_back(intrinsics_edit("intrinsics depth_scale 0", "\"depth_scale\": 5000.0",
                              "\"depth_scale\": 0", {"intrinsics.json", "depth_scale"}));
  c.push_back(intrinsics_edit("intrinsics size unlike the images", "\"width\": 80",
                              "\"width\": 160", {"80x60", "160x60"}));
  c.push_back({"depth scale off by 1000x",
               [](const fs::path& d) { return reconstruct(d, "--poses gt --depth-scale 5000000"); },
               3,
               {"outside the depth range", "depth scale"}});
  c.push_back({"--intrinsics file missing",
               [](const fs::path& d) {
                 return reconstruct(d, "--poses gt --intrinsics " + (d / "cam.json").string());
               },
               1,
               {"cam.json"}});
  c.push_back({"InfiniTAM calib.txt too short",
               [](const fs::path& d) {
                 fs::create_directories(d / "itm");
                 write(d / "itm" / "calib.txt", "640 480\n500 500\n");
                 write_png(d / "itm" / "0000.png", Image<uint16_t>(8, 6, uint16_t{1000}));
                 return reconstruct(d, "", (d / "itm").string());
               },
               1,
               {"calib.txt"}});
  c.push_back({"InfiniTAM image size 1e9",
               [](const fs::path& d) {
                 fs::create_directories(d / "itm");
                 write(
                     d / "itm" / "calib.txt",
                     "1e9 480\n500 500\n320 240\n\n640 480\n500 500\n320 240\n\n1 0 0 0\n0 1 0 0\n"
                     "0 0 1 0\n\naffine 0.001 0\n");
                 write_png(d / "itm" / "0000.png", Image<uint16_t>(8, 6, uint16_t{1000}));
                 return reconstruct(d, "", (d / "itm").string());
               },
               1,
               {"calib.txt"}});
  c.push_back({"7-Scenes pose malformed",
               [](const fs::path& d) {
                 const fs::path s = d / "seven" / "seq-01";
                 fs::create_directories(s);
                 write_png(s / "frame-000000.depth.png", Image<uint16_t>(640, 480, uint16_t{1000}));
                 write_png(s / "frame-000000.color.png", ColorImage(640, 480, Rgb8{}));
                 write(s / "frame-000000.pose.txt", "1 0 0\n0 1 0 0\n");
                 return reconstruct(d, "--poses gt", (d / "seven").string());
               },
               1,
               {"pose.txt"}});
  // Synthetic specs.
  c.push_back({"unknown synthetic scene",
               [](const fs::path& d) { return reconstruct(d, "", "'synthetic:nosuch'"); },
               1,
               {"nosuch"}});
  c.push_back({"synthetic frames not a number",
               [](const fs::path& d) { return reconstruct(d, "", "'synthetic:box?frames=abc'"); },
               1,
               {"frames", "abc"}});
  c.push_back(
      {"synthetic width 0",
       [](const fs::path& d) { return reconstruct(d, "", "'synthetic:box?frames=2&width=0'"); },
       1,
       {"width"}});
  c.push_back({"synthetic images too small to track",
               [](const fs::path& d) {
                 return reconstruct(d, "", "'synthetic:box?frames=3&noise=none&width=8&height=6'");
               },
               1,
               {"too small", "--icp-iterations"}});
  // Flags.
  const auto flag = [](const char* name, const std::string& extra, int code,
                       std::vector<std::string> expected) {
    return Case{name,
                [extra](const fs::path& d) {
                  return "reconstruct " + kScene + " --quiet --out " + (d / "out").string() + " " +
                         extra;
                },
                code, std::move(expected)};
  };
  c.push_back(flag("--voxel-size -1", "--voxel-size -1", 1, {"voxel_size_m"}));
  c.push_back(flag("--voxel-size 0", "--voxel-size 0", 1, {"voxel_size_m"}));
  c.push_back(flag("--voxel-size 1e-6", "--voxel-size 1e-6", 1, {"truncation_m", "512"}));
  // Micrometre voxels metres away: ray steps below a float's precision at that depth once
  // looped forever; the run must end, the full pool's drops counted.
  c.push_back(flag("--voxel-size 1e-6 with a full pool",
                   "--voxel-size 1e-6 --truncation 0.0004 --max-blocks 2000 --levels 1 --poses gt",
                   0, {"pool is full", "dropped"}));
  c.push_back(flag("--truncation 0", "--truncation 0", 1, {"truncation_m"}));
  c.push_back(flag("--truncation 2", "--truncation 2", 1, {"truncation_m"}));
  c.push_back(flag("--levels 0", "--levels 0", 1, {"levels"}));
  c.push_back(flag("--levels 5", "--levels 5", 1, {"levels"}));
  c.push_back(flag("--max-blocks 0", "--max-blocks 0", 1, {"max_blocks"}));
  c.push_back(flag("--hash-buckets 1000", "--hash-buckets 1000", 1, {"buckets_per_level"}));
  c.push_back(flag("--hash-excess -1", "--hash-excess -1", 1, {"excess_per_level"}));
  c.push_back(flag("--min-depth -1", "--min-depth -1", 1, {"min_m"}));
  c.push_back(flag("--max-depth below --min-depth", "--min-depth 1 --max-depth 0.5", 1, {"max_m"}));
  c.push_back(flag("--max-weight 0", "--max-weight 0", 1, {"max_weight"}));
  c.push_back(flag("--frames -5", "--frames -5", kUsage, {"--frames"}));
  c.push_back(flag("--threads -1", "--threads -1", kUsage, {"--threads"}));
  c.push_back(flag("--render-every -1", "--render-every -1", kUsage, {"--render-every"}));
  c.push_back(flag("--max-frames -2", "--max-frames -2", kUsage, {"--max-frames"}));
  c.push_back(flag("--icp-iterations 4,6,200", "--icp-iterations 4,6,200", 1, {"iterations"}));
  c.push_back(flag("--icp-model-subsample 3", "--icp-model-subsample 3", 1, {"model_subsample"}));
  c.push_back(flag("--icp-loss cauchy", "--icp-loss cauchy", 1, {"cauchy"}));
  c.push_back(flag("--refine foo", "--refine foo", 1, {"foo"}));
  c.push_back(
      flag("--split-threshold -1", "--levels 2 --split-threshold -1", 1, {"split_threshold"}));
  c.push_back(flag("--merge-threshold above split", "--levels 2 --merge-threshold 1", 1,
                   {"merge_threshold"}));
  c.push_back(flag("--depth-sampling linear", "--depth-sampling linear", 1, {"linear"}));
  c.push_back(flag("--sensor-noise loud", "--sensor-noise loud", kUsage, {"--sensor-noise"}));
  c.push_back(flag("--device gpu", "--device gpu", 1, {"gpu"}));
  c.push_back(flag("--device cuda", "--device cuda", 1, {"cuda:0"}));
  c.push_back({"--preset nosuch",
               [](const fs::path& d) { return reconstruct(d, "--poses gt --preset nosuch"); },
               1,
               {"nosuch", "tum_fr1"}});
  c.push_back(flag("--preset on a synthetic scene", "--preset tum_fr1", 1, {"--preset"}));
  c.push_back(flag("--depth-scale -5", "--depth-scale -5", 1, {"--depth-scale"}));
  c.push_back(flag("--on-bad-frame maybe", "--on-bad-frame maybe", kUsage, {"--on-bad-frame"}));
  c.push_back(flag("--read-ahead 65", "--read-ahead 65", kUsage, {"--read-ahead"}));
  c.push_back(flag("--read-threads -1", "--read-threads -1", kUsage, {"--read-threads"}));
  c.push_back(flag("--no-raycast with tracking", "--no-raycast", 1, {"raycast"}));
  c.push_back({"--out holds an earlier run",
               [](const fs::path& d) {
                 fs::create_directories(d / "out");
                 write(d / "out" / "mesh.ply", "old");
                 return reconstruct(d, "--poses gt");
               },
               1,
               {"--overwrite"}});
  c.push_back({"--out is a file",
               [](const fs::path& d) {
                 write(d / "out", "a file");
                 return reconstruct(d, "", kScene);
               },
               1,
               {"not a folder"}});
  // Other commands.
  c.push_back({"eval ate without the ground truth",
               [](const fs::path& d) {
                 return "eval ate --gt " + (d / "gt.txt").string() + " --est " +
                        (d / "seq" / "groundtruth.txt").string();
               },
               1,
               {"gt.txt"}});
  c.push_back({"eval ate with no common timestamps",
               [](const fs::path& d) {
                 write(d / "est.txt", "100 0 0 0 0 0 0 1\n101 0 0 0 0 0 0 1\n102 0 0 0 0 0 0 1\n");
                 return "eval ate --gt " + (d / "seq" / "groundtruth.txt").string() + " --est " +
                        (d / "est.txt").string();
               },
               1,
               {"est.txt"}});
  c.push_back({"eval ate with duplicated timestamps",
               [](const fs::path& d) {
                 std::string gt = read(d / "seq" / "groundtruth.txt");
                 write(d / "est.txt", gt + gt.substr(gt.find("\n0.000000") + 1));
                 return "eval ate --gt " + (d / "seq" / "groundtruth.txt").string() + " --est " +
                        (d / "est.txt").string();
               },
               0,
               {"est.txt", "duplicated"}});
  c.push_back({"synth over an existing sequence",
               [](const fs::path& d) {
                 return "synth --scene box --frames 2 --width 80 --height 60 --out " +
                        (d / "seq").string();
               },
               1,
               {"--overwrite"}});
  c.push_back({"info on a missing folder",
               [](const fs::path&) { return std::string("info /no/such/set"); },
               1,
               {"/no/such/set"}});
  return c;
}

/// The sequence every case starts from, exported once.
const fs::path& base_sequence() {
  static const test::TempDir dir;
  static const fs::path seq = [] {
    const fs::path p = dir / "seq";
    const auto r = run_hivox(
        "synth --scene box --frames 4 --width 80 --height 60 --noise none "
        "--out " +
        p.string());
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return p;
  }();
  return seq;
}

TEST(BadInput, EveryCaseGivesItsErrorAndNothingCrashes) {
  const std::vector<Case> all = cases();
  EXPECT_GE(all.size(), 60u);
  for (const Case& c : all) {
    SCOPED_TRACE(c.name);
    const test::TempDir dir;
    fs::copy(base_sequence(), dir / "seq", fs::copy_options::recursive);
    const std::string args = c.setup(dir.path());
    const test::CliRun r = run_hivox(args);
    if (c.exit_code == kUsage)
      EXPECT_GE(r.exit_code, 100) << "hivox " << args << "\n" << r.output;
    else
      EXPECT_EQ(r.exit_code, c.exit_code) << "hivox " << args << "\n" << r.output;
    for (const std::string& part : c.expected)
      EXPECT_TRUE(test::contains(r.output, part))
          << "the output lacks '" << part << "'\nhivox " << args << "\n"
          << r.output;
    EXPECT_FALSE(test::contains(r.output, "unexpected failure")) << r.output;
  }
}

}  // namespace
}  // namespace hivox

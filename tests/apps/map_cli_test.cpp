// The map-file round trip as a user runs it: `reconstruct --save-map`, then `mesh`, `info`,
// `render`, `export` and `reconstruct --map` on the saved file; and what each says about bad
// input.

#include <gtest/gtest.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <string>

#include "apps/cli_util.h"
#include "hivox/io/atomic_file.h"
#include "hivox/io/image_io.h"
#include "hivox/io/map_file.h"
#include "hivox/io/ply.h"
#include "hivox/io/trajectory_io.h"
#include "test_util.h"

namespace hivox {
namespace {

using test::run_hivox;
namespace fs = std::filesystem;

const std::string kScene = "'synthetic:desk?frames=40&noise=kinect&width=160&height=120'";
const std::string kSettings = " --poses gt --voxel-size 0.008 --truncation 0.064 --quiet";

/// One saved run shared by the tests of this file (made once).
class MapCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TempDir;
    const auto r = run_hivox("reconstruct " + kScene + kSettings + " --frames 12 --save-map " +
                             map().string() + " --out " + run().string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static fs::path map() { return *dir_ / "desk.hvx"; }
  static fs::path run() { return *dir_ / "run"; }
  static test::TempDir* dir_;
};
test::TempDir* MapCli::dir_ = nullptr;

TEST_F(MapCli, MeshOfTheSavedMapIsTheRunsMesh) {
  test::TempDir dir;
  const auto r = run_hivox("mesh " + map().string() + " --out " + (dir / "m.ply").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(test::contains(r.output, "loaded in")) << r.output;
  EXPECT_TRUE(read_whole_file(dir / "m.ply") == read_whole_file(run() / "mesh.ply"));
}

TEST_F(MapCli, MeshAsObjWithLevelColoursBoundsAndPieces) {
  test::TempDir dir;
  ASSERT_EQ(
      run_hivox("mesh " + map().string() + " --quiet --out " + (dir / "m.obj").string()).exit_code,
      0);
  const TriangleMesh ply = read_ply(run() / "mesh.ply");
  std::ifstream obj(dir / "m.obj");
  int64_t v = 0, vn = 0, f = 0;
  for (std::string line; std::getline(obj, line);) {
    v += line.rfind("v ", 0) == 0;
    vn += line.rfind("vn ", 0) == 0;
    f += line.rfind("f ", 0) == 0;
  }
  EXPECT_EQ(v, ply.vertex_count());
  EXPECT_EQ(vn, ply.vertex_count());
  EXPECT_EQ(f, ply.triangle_count());

  ASSERT_EQ(run_hivox("mesh " + map().string() + " --quiet --level-colors --out " +
                      (dir / "levels.ply").string())
                .exit_code,
            0);
  const TriangleMesh levels = read_ply(dir / "levels.ply");
  ASSERT_EQ(levels.colors.size(), levels.levels.size());
  for (std::size_t i = 0; i < levels.colors.size(); i += 97)
    for (std::size_t j = 0; j < levels.colors.size(); j += 89)
      if (levels.levels[i] == levels.levels[j]) {
        EXPECT_TRUE(levels.colors[i] == levels.colors[j]);
      }

  // Bounds: every vertex inside; fewer triangles than the whole.
  ASSERT_EQ(run_hivox("mesh " + map().string() +
                      " --quiet --bounds=-0.5,-0.5,0.5,0.5,0.5,1.5 "
                      "--out " +
                      (dir / "box.ply").string())
                .exit_code,
            0);
  const TriangleMesh box = read_ply(dir / "box.ply");
  EXPECT_GT(box.triangle_count(), 100);
  EXPECT_LT(box.triangle_count(), ply.triangle_count());
  for (const Vec3f& p : box.positions_w) {
    EXPECT_TRUE(p.x >= -0.5f && p.x <= 0.5f && p.y >= -0.5f && p.y <= 0.5f && p.z >= 0.5f &&
                p.z <= 1.5f);
  }
  // Small pieces: the count removed is reported and adds up.
  const auto pieces = run_hivox("mesh " + map().string() + " --min-piece 500 --out " +
                                (dir / "pieces.ply").string());
  ASSERT_EQ(pieces.exit_code, 0) << pieces.output;
  const std::size_t at = pieces.output.rfind("triangles)");
  const std::size_t from = pieces.output.rfind('(', at);
  ASSERT_NE(at, std::string::npos) << pieces.output;
  const int64_t removed = std::stoll(pieces.output.substr(from + 1));
  EXPECT_TRUE(test::contains(pieces.output, "pieces of fewer than 500 triangles")) << pieces.output;
  EXPECT_EQ(read_ply(dir / "pieces.ply").triangle_count() + removed, ply.triangle_count());
}

TEST_F(MapCli, InfoPrintsLevelsBlocksMemoryBoxAndSettings) {
  const auto r = run_hivox("info " + map().string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const MapFileInfo info = read_map_file_info(map());
  for (const std::string& part :
       {std::string("format version 1"), std::string("levels: 3"),
        std::string("level 0: voxel 8.0 mm"), std::string("level 2: voxel 32.0 mm"),
        std::string("memory:"), std::string("bounding box: ["), std::string("frames fused: 12"),
        std::string("max weight 100"), std::to_string(info.blocks_per_level[0]) + " blocks"})
    EXPECT_TRUE(test::contains(r.output, part)) << "no '" << part << "' in\n" << r.output;
}

TEST_F(MapCli, RenderFromAPoseAndAlongATrajectory) {
  test::TempDir dir;
  const auto poses = read_tum_trajectory(run() / "trajectory.txt");
  ASSERT_EQ(poses.size(), 12u);
  const std::array<double, 7> t = to_tum(poses.back().T_wc);
  const std::string pose =
      fmt::format("'{} {} {} {} {} {} {}'", t[0], t[1], t[2], t[3], t[4], t[5], t[6]);
  auto r = run_hivox("render " + map().string() + " --pose " + pose + " --out " +
                     (dir / "one").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // The render from the last pose is the run's own render from there.
  for (const char* name : {"depth.png", "normals.png", "shaded.png", "color.png", "levels.png"}) {
    ASSERT_TRUE(fs::exists(dir / "one" / name)) << name;
  }
  EXPECT_TRUE(read_whole_file(dir / "one" / "depth.png") == read_whole_file(run() / "depth.png"));
  EXPECT_TRUE(read_whole_file(dir / "one" / "color.png") == read_whole_file(run() / "color.png"));
  r = run_hivox("render " + map().string() + " --quiet --every 4 --trajectory " +
                (run() / "trajectory.txt").string() + " --out " + (dir / "many").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir / "many" / "frame000002_shaded.png"));
  EXPECT_FALSE(fs::exists(dir / "many" / "frame000003_shaded.png"));
}

// numpy reads the export; its arrays agree with the map file's counts and the voxels' meaning.
TEST_F(MapCli, ExportIsReadByNumpy) {
  if (test::run_shell("/usr/bin/python3 -c 'import numpy'").exit_code != 0)
    GTEST_SKIP() << "python3 with numpy not installed (scripts/install-deps installs it)";
  test::TempDir dir;
  const auto r = run_hivox("export " + map().string() + " --out " + (dir / "m.npz").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const MapFileInfo info = read_map_file_info(map());
  const std::string script =
      "import numpy as np\n"
      "m = np.load('" +
      (dir / "m.npz").string() +
      "')\n"
      "print('sizes', ' '.join(str(round(float(s), 4)) for s in m['voxel_size_m']))\n"
      "print('mu', round(float(m['truncation_m']), 4))\n"
      "for l in range(3):\n"
      "  c, t, w, col = (m[f'level{l}_{k}'] for k in ('coords', 'tsdf', 'weight', 'color'))\n"
      "  assert c.shape == (len(c), 3) and c.dtype == np.int32\n"
      "  assert t.shape == (len(c), 8, 8, 8) and t.dtype == np.float32\n"
      "  assert w.shape == t.shape and w.dtype == np.uint16 and col.shape == t.shape + (3,)\n"
      "  assert (np.abs(t) <= float(m['truncation_m']) + 1e-6).all()\n"
      "  assert (t[w == 0] == np.float32(m['truncation_m'])).all()\n"
      "  print('level', l, len(c), int((w > 0).sum()), int(((t < 0) & (w > 0)).sum()))\n";
  test::write_text(dir / "check.py", script);
  const auto py = test::run_shell("/usr/bin/python3 " + (dir / "check.py").string());
  ASSERT_EQ(py.exit_code, 0) << py.output;
  EXPECT_TRUE(test::contains(py.output, "sizes 0.008 0.016 0.032")) << py.output;
  EXPECT_TRUE(test::contains(py.output, "mu 0.064")) << py.output;
  for (int l = 0; l < 3; ++l)
    EXPECT_TRUE(test::contains(
        py.output,
        fmt::format("level {} {} ", l, info.blocks_per_level[static_cast<std::size_t>(l)])))
        << py.output;
}

// Stop after some frames, continue from the saved map with the rest: the map of one whole run.
TEST_F(MapCli, ContinuingWithTheCliEqualsOneRun) {
  test::TempDir dir;
  const std::string base = "reconstruct " + kScene + kSettings;
  ASSERT_EQ(run_hivox(base + " --frames 5 --save-map " + (dir / "a.hvx").string() + " --out " +
                      (dir / "a").string())
                .exit_code,
            0);
  // Left out, --voxel-size and --truncation come from the file.
  const auto r =
      run_hivox("reconstruct " + kScene + " --poses gt --quiet --first-frame 5 --frames 7 --map " +
                (dir / "a.hvx").string() + " --save-map " + (dir / "b.hvx").string() + " --out " +
                (dir / "b").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(read_whole_file(dir / "b.hvx") == read_whole_file(map()));
  EXPECT_TRUE(read_whole_file(dir / "b" / "mesh.ply") == read_whole_file(run() / "mesh.ply"));
}

TEST_F(MapCli, BadInputGetsOneClearLine) {
  test::TempDir dir;
  struct Case {
    std::string args, expect;
  };
  const std::string m = map().string();
  test::write_text(dir / "notes.txt", "not a map\n");
  const std::vector<Case> cases = {
      {"mesh " + (dir / "missing.hvx").string() + " --out x.ply",
       "missing.hvx: file does not exist"},
      {"mesh " + (dir / "notes.txt").string() + " --out x.ply", "not a hivox map file"},
      {"mesh " + m + " --out " + (dir / "x.stl").string(), "must end in .ply or .obj"},
      {"mesh " + m + " --bounds 1,2,3 --out " + (dir / "x.ply").string(),
       "--bounds '1,2,3': 3 numbers"},
      {"mesh " + m + " --bounds=1,1,1,0,0,0 --out " + (dir / "x.ply").string(), "min <= max"},
      {"mesh " + m + " --min-weight 0 --out " + (dir / "x.ply").string(), "min_weight"},
      {"render " + m + " --out " + (dir / "r").string(), "one of --pose and --trajectory"},
      {"render " + m + " --pose '0 0 0' --out " + (dir / "r").string(), "3 numbers, expected 7"},
      {"render " + m + " --pose '0 0 0 0 0 0 1' --camera 1,2 --out " + (dir / "r").string(),
       "--camera"},
      {"export " + m + " --out " + (dir / "x.zip").string(), "*.npz"},
      {"reconstruct " + kScene + " --poses gt --quiet --voxel-size 0.005 --map " + m + " --out " +
           (dir / "c").string(),
       "voxel size"},
      {"reconstruct " + kScene + " --poses gt --quiet --no-color --map " + m + " --out " +
           (dir / "c").string(),
       "colour"},
      {"reconstruct " + kScene + " --poses gt --quiet --map " + m + " --save-map " + m + " --out " +
           (dir / "c").string(),
       "same file"},
      {"reconstruct " + kScene + " --poses gt --quiet --first-frame 40 --out " +
           (dir / "c").string(),
       "first frame 40, but the dataset has 40 frames"},
  };
  for (const Case& c : cases) {
    const auto r = run_hivox(c.args);
    EXPECT_NE(r.exit_code, 0) << c.args;
    EXPECT_TRUE(test::contains(r.output, c.expect))
        << c.args << "\nexpected '" << c.expect << "' in:\n"
        << r.output;
    EXPECT_LE(std::count(r.output.begin(), r.output.end(), '\n'), 2) << r.output;
  }
  EXPECT_EQ(read_map_file_info(m).session.frames_fused, 12) << "the map is untouched";
}

// An interrupted run saves its map too, with the frames fused so far.
TEST(MapCliInterrupt, AnInterruptedRunSavesItsMap) {
  test::TempDir dir;
  const auto r = test::run_hivox_interrupted(
      "reconstruct 'synthetic:desk?frames=2000&noise=none&width=160&height=120' --poses gt "
      "--levels 1 --voxel-size 0.01 --truncation 0.04 --save-map " +
          (dir / "m.hvx").string() + " --out " + (dir / "run").string(),
      50, (dir / "log.txt").string());
  EXPECT_EQ(r.exit_code, 130) << r.output;
  const auto poses = read_tum_trajectory(dir / "run" / "trajectory.txt");
  ASSERT_GE(poses.size(), 50u) << r.output;
  const MapFileInfo info = read_map_file_info(dir / "m.hvx");
  EXPECT_EQ(info.session.frames_fused, static_cast<int64_t>(poses.size()));
  const auto mesh =
      run_hivox("mesh " + (dir / "m.hvx").string() + " --quiet --out " + (dir / "m.ply").string());
  ASSERT_EQ(mesh.exit_code, 0) << mesh.output;
  EXPECT_TRUE(read_whole_file(dir / "m.ply") == read_whole_file(dir / "run" / "mesh.ply"));
}

}  // namespace
}  // namespace hivox

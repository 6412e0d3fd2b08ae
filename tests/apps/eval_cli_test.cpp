// `hivox eval ate` as a user meets it: JSON and table output on written trajectories, one-line
// errors.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include <nlohmann/json.hpp>

#include "apps/cli_util.h"
#include "eval/trajectory_test_util.h"
#include "hivox/io/obj.h"
#include "hivox/io/ply.h"
#include "hivox/io/trajectory_io.h"
#include "test_util.h"

namespace hivox {
namespace {

using test::CliRun;
using test::contains;
using test::run_hivox;

// Ground truth and an estimate with a known ATE after alignment (see trajectory_test_util.h):
// offsets of 1 cm and 2 cm in alternation, then a large rigid motion.
struct AteFiles {
  test::TempDir dir;
  std::string gt = (dir / "groundtruth.txt").string();
  std::string est = (dir / "trajectory.txt").string();
  double rmse_m = std::sqrt((0.01 * 0.01 + 0.02 * 0.02) / 2.0);

  AteFiles() {
    const auto poses = test::loop_trajectory(120);
    write_tum_trajectory(gt, poses);
    write_tum_trajectory(
        est, test::perturbed(poses, {0.01, 0, 0}, {0, 0, 0.02}, test::some_rigid_motion()));
  }
};

TEST(EvalCli, AteJsonIsOneObjectWithTheKnownRmse) {
  const AteFiles f;
  const CliRun r = run_hivox("eval ate --gt " + f.gt + " --est " + f.est + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  nlohmann::json j;
  ASSERT_NO_THROW(j = nlohmann::json::parse(r.output)) << "not one JSON object:\n" << r.output;
  ASSERT_TRUE(j.is_object());
  for (const char* key : {"rmse_m", "mean_m", "median_m", "min_m", "max_m", "matched"})
    ASSERT_TRUE(j.contains(key)) << key << " missing in " << r.output;
  EXPECT_EQ(j["matched"].get<std::size_t>(), 120u);
  // The files hold 9 decimals: the known values within 1e-7 m.
  EXPECT_NEAR(j["rmse_m"].get<double>(), f.rmse_m, 1e-7);
  EXPECT_NEAR(j["mean_m"].get<double>(), 0.015, 1e-7);
  EXPECT_NEAR(j["median_m"].get<double>(), 0.015, 1e-7);
  EXPECT_NEAR(j["min_m"].get<double>(), 0.01, 1e-7);
  EXPECT_NEAR(j["max_m"].get<double>(), 0.02, 1e-7);

  const CliRun raw = run_hivox("eval ate --gt " + f.gt + " --est " + f.est + " --json --no-align");
  ASSERT_EQ(raw.exit_code, 0) << raw.output;
  EXPECT_GT(nlohmann::json::parse(raw.output)["rmse_m"].get<double>(), 1.0);
}

TEST(EvalCli, AteTableIsReadable) {
  const AteFiles f;
  const CliRun r = run_hivox("eval ate --gt " + f.gt + " --est " + f.est);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* part : {"matched:   120 of 120 estimated poses", "rmse", "mean", "median", "max",
                           "1.58 cm", "alignment: rotation 40.000 deg"})
    EXPECT_TRUE(contains(r.output, part)) << part << " missing in:\n" << r.output;
}

TEST(EvalCli, AteHelpNamesItsOptions) {
  const CliRun eval = run_hivox("eval --help");
  EXPECT_EQ(eval.exit_code, 0);
  EXPECT_TRUE(contains(eval.output, "ate")) << eval.output;
  const CliRun r = run_hivox("eval ate --help");
  EXPECT_EQ(r.exit_code, 0);
  for (const char* part : {"--gt", "--est", "--max-dt", "--no-align", "--json", "TUM", "Examples"})
    EXPECT_TRUE(contains(r.output, part)) << part << " missing in:\n" << r.output;
}

TEST(EvalCli, AteBadInputIsOneLineNamingTheProblem) {
  const AteFiles f;
  const std::string missing = (f.dir / "missing.txt").string();
  const std::string late = (f.dir / "late.txt").string();
  auto poses = read_tum_trajectory(f.est);
  for (std::size_t i = 2; i < poses.size(); ++i) poses[i].timestamp_s += 50.0;
  write_tum_trajectory(late, poses);
  const std::string empty = (f.dir / "empty.txt").string();
  test::write_text(empty, "# nothing\n");

  const struct {
    std::string args, says;
  } cases[] = {
      {"--gt " + missing + " --est " + f.est, missing},
      {"--gt " + f.gt + " --est " + empty, empty},
      {"--gt " + f.gt + " --est " + late, "only 2 of 120"},
      {"--gt " + f.gt + " --est " + f.est + " --max-dt 0", "--max-dt"},
  };
  for (const auto& c : cases) {
    const CliRun r = run_hivox("eval ate " + c.args);
    EXPECT_EQ(r.exit_code, 1) << c.args << "\n" << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << c.args << "\n" << r.output;
    EXPECT_TRUE(contains(r.output, "[error]")) << r.output;
    EXPECT_TRUE(contains(r.output, c.says)) << c.says << " missing in:\n" << r.output;
  }
  EXPECT_NE(run_hivox("eval ate --est " + f.est).exit_code, 0);  // --gt is required
}

/// A 1 m square of two triangles at height z.
TriangleMesh square(float z) {
  TriangleMesh m;
  m.positions_w = {{0, 0, z}, {1, 0, z}, {1, 1, z}, {0, 1, z}};
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  return m;
}

TEST(EvalCli, MeshComparesAnyTwoFormatsAndReportsTheShift) {
  test::TempDir dir;
  write_ply(dir / "ref.ply", square(0.0f));
  write_obj(dir / "shifted.obj", square(0.004f));
  const CliRun r = run_hivox("eval mesh --reference " + (dir / "ref.ply").string() + " --mesh " +
                             (dir / "shifted.obj").string() + " --samples 5000 --json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto j = nlohmann::json::parse(r.output);
  EXPECT_NEAR(j["accuracy"]["mean_m"].get<double>(), 0.004, 1e-6);
  EXPECT_NEAR(j["completeness"]["max_m"].get<double>(), 0.004, 1e-6);
  EXPECT_NEAR(j["chamfer_m"].get<double>(), 0.004, 1e-6);
  ASSERT_EQ(j["fscores"].size(), 2u);  // 5 mm and 1 cm
  EXPECT_EQ(j["fscores"][0]["fscore"].get<double>(), 1.0);
  const CliRun table =
      run_hivox("eval mesh --reference " + (dir / "ref.ply").string() + " --mesh " +
                (dir / "shifted.obj").string() + " --samples 5000 --thresholds 0.001,0.005");
  EXPECT_EQ(table.exit_code, 0) << table.output;
  EXPECT_TRUE(contains(table.output, "within 1 mm: precision 0.0 %")) << table.output;
  EXPECT_TRUE(contains(table.output, "within 5 mm: precision 100.0 %")) << table.output;
  // Bad input: one line naming it.
  for (const auto& [args, words] : std::vector<std::pair<std::string, std::string>>{
           {"eval mesh --reference " + (dir / "none.ply").string() + " --mesh " +
                (dir / "ref.ply").string(),
            "none.ply"},
           {"eval mesh --reference " + (dir / "ref.ply").string() + " --mesh " +
                (dir / "ref.stl").string(),
            ".ply, .obj, .off"},
           {"eval mesh --reference " + (dir / "ref.ply").string() + " --mesh " +
                (dir / "ref.ply").string() + " --samples 0",
            "samples"}}) {
    const CliRun bad = run_hivox(args);
    EXPECT_EQ(bad.exit_code, 1) << args << "\n" << bad.output;
    EXPECT_EQ(std::count(bad.output.begin(), bad.output.end(), '\n'), 1) << bad.output;
    EXPECT_TRUE(contains(bad.output, words)) << bad.output;
  }
}

}  // namespace
}  // namespace hivox

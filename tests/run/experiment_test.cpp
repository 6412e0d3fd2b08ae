// The experiment (paper §VI) on a small synthetic sequence: the three configurations see the same
// frames from the same poses, the fixed coarse grid uses the fewest blocks and scores the largest
// sdf-error, the files a person reads are all there and agree with the result.

#include "hivox/run/experiment.h"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "hivox/core/error.h"
#include "hivox/io/atomic_file.h"
#include "run/small_run.h"
#include "test_util.h"

namespace hivox {
namespace {

namespace fs = std::filesystem;

ExperimentParams small_experiment(const fs::path& out) {
  ExperimentParams p;
  p.configs = hierarchy_configs(test::small_run().reconstruction);
  p.poses = PoseSpec::parse("gt");
  p.tracked = TrackedRuns::Never;
  p.sdf.samples = 20000;
  p.mesh_eval.samples = 20000;
  p.out_dir = out;
  return p;
}

TEST(Experiment, HierarchyConfigsAreTheFinestCoarsestAndAdaptive) {
  ReconstructionParams adaptive = test::small_run().reconstruction;
  adaptive.map.levels = 3;
  adaptive.map.voxel_size_m = 0.002f;
  const std::vector<ExperimentConfig> c = hierarchy_configs(adaptive);
  ASSERT_EQ(c.size(), 3u);
  EXPECT_EQ(c[0].name, "fixed 2 mm");
  EXPECT_EQ(c[0].slug, "fixed-2mm");
  EXPECT_EQ(c[0].params.map.levels, 1);
  EXPECT_FLOAT_EQ(c[0].params.map.voxel_size_m, 0.002f);
  EXPECT_EQ(c[1].slug, "fixed-8mm");
  EXPECT_EQ(c[1].params.map.levels, 1);
  EXPECT_FLOAT_EQ(c[1].params.map.voxel_size_m, 0.008f);
  EXPECT_EQ(c[2].slug, "adaptive");
  EXPECT_EQ(c[2].params.map.levels, 3);
  EXPECT_EQ(c[0].params.map.max_blocks, 4 * adaptive.map.max_blocks);
  EXPECT_EQ(c[2].params.map.max_blocks, adaptive.map.max_blocks);
  // The truncation band is the same metric band for all (paper: one mu for every level).
  for (const ExperimentConfig& x : c)
    EXPECT_FLOAT_EQ(x.params.map.truncation_m, adaptive.map.truncation_m);
  adaptive.map.levels = 1;
  EXPECT_THROW(hierarchy_configs(adaptive), Error);
}

TEST(Experiment, ComparesTheConfigurationsOnTheSameFramesAndPoses) {
  test::TempDir tmp;
  SyntheticDataset data = test::small_desk(10);
  const ExperimentParams p = small_experiment(tmp / "exp");
  const ExperimentResult r = run_experiment(data, p);
  ASSERT_EQ(r.configs.size(), 3u);
  EXPECT_EQ(r.frames, 10u);
  EXPECT_FALSE(r.stopped);
  EXPECT_EQ(r.sdf_samples, 20000);
  const ConfigResult &fine = r.configs[0], &coarse = r.configs[1], &adaptive = r.configs[2];
  for (const ConfigResult& c : r.configs) {
    EXPECT_EQ(c.run.frames_fused, 10u) << c.config.name;
    EXPECT_FALSE(c.tracked.has_value());
    EXPECT_GT(c.blocks, 0);
    EXPECT_GE(c.peak_blocks, c.blocks);
    EXPECT_GT(c.sdf.coverage, 0.9) << c.config.name;
    EXPECT_GT(c.times.total_ms, 0.0);
  }
  // Coarse voxels: 8x fewer per volume, the fewest blocks, the largest error at the fine mesh.
  EXPECT_DOUBLE_EQ(fine.block_saving, 0.0);
  EXPECT_LT(coarse.blocks, adaptive.blocks);
  EXPECT_LT(adaptive.blocks, fine.blocks);
  EXPECT_GT(coarse.sdf.mean_abs_sdf_m, adaptive.sdf.mean_abs_sdf_m);
  EXPECT_GT(adaptive.sdf.mean_abs_sdf_m, fine.sdf.mean_abs_sdf_m);
  EXPECT_NEAR(adaptive.block_saving,
              1.0 - static_cast<double>(adaptive.blocks) / static_cast<double>(fine.blocks), 1e-12);
  ASSERT_EQ(adaptive.blocks_per_level.size(), 2u);
  EXPECT_EQ(adaptive.blocks_per_level[0] + adaptive.blocks_per_level[1], adaptive.blocks);

  // The files.
  const fs::path out = tmp / "exp";
  for (const char* f :
       {"report.md", "report.json", "blocks.csv", "sdf_points.csv", "runs/fixed-10mm/mesh.ply",
        "runs/fixed-10mm.hvx", "runs/adaptive/stats.json", "renders/adaptive_overview_levels.png",
        "renders/fixed-20mm_close_shaded.png"})
    EXPECT_TRUE(fs::exists(out / f)) << f;
  const nlohmann::json j = nlohmann::json::parse(read_whole_file(out / "report.json"));
  ASSERT_EQ(j["configs"].size(), 3u);
  EXPECT_EQ(j["frames"].get<std::size_t>(), 10u);
  EXPECT_EQ(j["configs"][2]["blocks"].get<int64_t>(), adaptive.blocks);
  EXPECT_DOUBLE_EQ(j["configs"][1]["sdf_error"]["ratio_to_coarsest_fixed"].get<double>(), 1.0);
  EXPECT_NEAR(j["configs"][2]["sdf_error"]["ratio_to_coarsest_fixed"].get<double>(),
              adaptive.sdf.mean_abs_sdf_m / coarse.sdf.mean_abs_sdf_m, 1e-12);
  // blocks.csv: a header and one row per frame whose counts are the runs' own.
  std::ifstream csv(out / "blocks.csv");
  std::string header, line, last;
  std::getline(csv, header);
  EXPECT_EQ(header,
            "frame,fixed-10mm,fixed-10mm_level0,fixed-20mm,fixed-20mm_level0,adaptive,"
            "adaptive_level0,adaptive_level1");
  int rows = 0;
  while (std::getline(csv, line)) {
    ++rows;
    last = line;
  }
  EXPECT_EQ(rows, 10);
  std::stringstream fields(last);
  std::vector<int64_t> v;
  for (std::string x; std::getline(fields, x, ',');) v.push_back(std::stoll(x));
  ASSERT_EQ(v.size(), 8u);
  EXPECT_EQ(v[1], fine.blocks);
  EXPECT_EQ(v[3], coarse.blocks);
  EXPECT_EQ(v[5], adaptive.blocks);
  const std::string md = read_whole_file(out / "report.md");
  for (const char* s : {"Blocks and memory", "sdf-error", "| adaptive 10 mm-20 mm |", "Speed"})
    EXPECT_TRUE(test::contains(md, s)) << s;
}

TEST(Experiment, AReferenceMeshGivesAccuracyAndTrackedRunsGiveAte) {
  test::TempDir tmp;
  SyntheticDataset data = test::small_desk(6);
  // A first experiment's fixed finest mesh is the reference of the second: that configuration
  // then meets it exactly (the same frames, poses and settings make the same mesh).
  run_experiment(data, small_experiment(tmp / "a"));
  ExperimentParams p = small_experiment(tmp / "b");
  p.reference_mesh = tmp / "a" / "runs" / "fixed-10mm" / "mesh.ply";
  p.tracked = TrackedRuns::Always;
  const ExperimentResult r = run_experiment(data, p);
  for (const ConfigResult& c : r.configs) {
    ASSERT_TRUE(c.mesh_eval.has_value()) << c.config.name;
    ASSERT_TRUE(c.tracked.has_value()) << c.config.name;
    EXPECT_TRUE(c.tracked->ate.has_value()) << c.config.name;
    EXPECT_EQ(c.tracked->frames_fused + c.tracked->frames_lost, 6u);
  }
  // Completeness counts the part of the reference the frames saw: here, nearly all of it (the
  // reference is made of these frames).
  EXPECT_EQ(r.reference_observed_views, 6u);
  EXPECT_GT(r.configs[0].mesh_eval->reference_kept, 0.8);
  EXPECT_LE(r.configs[0].mesh_eval->reference_kept, 1.0);
  EXPECT_LT(r.configs[0].mesh_eval->accuracy.max_m, 1e-5);
  EXPECT_GT(r.configs[1].mesh_eval->accuracy.mean_m, 10 * r.configs[0].mesh_eval->accuracy.mean_m);
  const std::string md = read_whole_file(tmp / "b" / "report.md");
  EXPECT_TRUE(test::contains(md, "Mesh against the reference mesh")) << md;
  EXPECT_TRUE(test::contains(md, "Tracked runs")) << md;
  EXPECT_TRUE(fs::exists(tmp / "b" / "runs" / "adaptive-tracked" / "trajectory.txt"));
}

TEST(Experiment, RefusesBadSettingsAndAFolderThatHoldsFiles) {
  test::TempDir tmp;
  SyntheticDataset data = test::small_desk(3);
  ExperimentParams p = small_experiment(tmp / "exp");
  p.configs[1].slug = p.configs[0].slug;
  EXPECT_THROW(run_experiment(data, p), Error);
  p = small_experiment(tmp / "exp");
  p.configs[2].slug = "Has Space";
  EXPECT_THROW(run_experiment(data, p), Error);
  p = small_experiment(tmp / "exp");
  p.reference_mesh = tmp / "missing.ply";
  EXPECT_THROW(run_experiment(data, p), Error);
  test::write_text(tmp / "exp" / "old.txt", "x");
  p = small_experiment(tmp / "exp");
  EXPECT_THROW(run_experiment(data, p), Error);
  EXPECT_TRUE(fs::exists(tmp / "exp" / "old.txt"));  // nothing lost
  p.overwrite = true;
  p.configs.resize(2);
  EXPECT_NO_THROW(run_experiment(data, p));
  EXPECT_FALSE(fs::exists(tmp / "exp" / "old.txt"));
}

}  // namespace
}  // namespace hivox

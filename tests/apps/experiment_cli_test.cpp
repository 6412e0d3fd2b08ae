// `hivox experiment` and `hivox eval sdf-error` as a user meets them: the report, figures (when
// matplotlib is there), extra configurations from a run's config.json, the sdf-error from the
// saved maps agreeing with the experiment's own, one-line errors.

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "apps/cli_util.h"
#include "hivox/io/atomic_file.h"
#include "test_util.h"

namespace hivox {
namespace {

namespace fs = std::filesystem;
using test::CliRun;
using test::contains;
using test::run_hivox;

const std::string kData = "'synthetic:desk?frames=6&noise=none&width=160&height=120'";
const std::string kTables = " --max-blocks 65536 --hash-buckets 16384 --hash-excess 16384";
const std::string kSmall = " --voxel-size 0.01 --truncation 0.04 --levels 2" + kTables;

bool have_matplotlib() {
  return std::system("/usr/bin/python3 -c 'import matplotlib, numpy' > /dev/null 2>&1") == 0;
}

/// One experiment, made once for the tests that read it.
class ExperimentCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TempDir;
    run_ = new CliRun(run_hivox("experiment " + kData + kSmall +
                                " --samples 5000 --mesh-samples 5000 --tracked never --out " +
                                (*dir_ / "exp").string() + " 2>&1"));
  }
  static void TearDownTestSuite() {
    delete run_;
    delete dir_;
  }
  static fs::path out() { return *dir_ / "exp"; }
  static test::TempDir* dir_;
  static CliRun* run_;
};
test::TempDir* ExperimentCli::dir_ = nullptr;
CliRun* ExperimentCli::run_ = nullptr;

TEST_F(ExperimentCli, WritesTheReportWithProgressAndFigures) {
  ASSERT_EQ(run_->exit_code, 0) << run_->output;
  for (const char* s : {"[1/3] fixed 10 mm: same poses (gt)", "[3/3] adaptive 10 mm-20 mm",
                        "frame 6/6", "saving", "report: "})
    EXPECT_TRUE(contains(run_->output, s)) << s << " not in:\n" << run_->output;
  const std::string md = read_whole_file(out() / "report.md");
  if (have_matplotlib()) {
    for (const char* f : {"figures/blocks.png", "figures/renders.png", "figures/sdf_error.png",
                          "figures/tradeoff.png"}) {
      EXPECT_TRUE(fs::exists(out() / f)) << f;
      EXPECT_TRUE(contains(md, std::string("](") + f + ")")) << f << " not shown in report.md";
    }
  } else {
    EXPECT_TRUE(contains(run_->output, "figures not made")) << run_->output;
    EXPECT_TRUE(contains(md, "None yet"));
  }
}

TEST_F(ExperimentCli, SdfErrorFromTheSavedMapsAgreesWithTheExperiment) {
  ASSERT_EQ(run_->exit_code, 0) << run_->output;
  const fs::path runs = out() / "runs";
  const CliRun r = run_hivox("eval sdf-error --fine " + (runs / "fixed-10mm.hvx").string() +
                             " --coarse " + (runs / "fixed-20mm.hvx").string() + " --adaptive " +
                             (runs / "adaptive.hvx").string() + " --samples 5000 --json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json j = nlohmann::json::parse(r.output);
  const nlohmann::json report = nlohmann::json::parse(read_whole_file(out() / "report.json"));
  ASSERT_EQ(j["maps"].size(), 3u);
  EXPECT_EQ(j["samples"].get<int64_t>(), 5000);
  // The same mesh, seed and maps: the same points and scores.
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(j["maps"][i]["mean_m"].get<double>(),
                report["configs"][i]["sdf_error"]["mean_m"].get<double>(), 1e-9)
        << i;
  EXPECT_GT(j["maps"][1]["mean_m"].get<double>(), j["maps"][2]["mean_m"].get<double>());
  EXPECT_DOUBLE_EQ(j["maps"][1]["ratio_to_coarsest"].get<double>(), 1.0);

  const CliRun table =
      run_hivox("eval sdf-error --fine " + (runs / "fixed-10mm.hvx").string() + " --adaptive " +
                (runs / "adaptive.hvx").string() + " --samples 2000");
  ASSERT_EQ(table.exit_code, 0) << table.output;
  EXPECT_TRUE(contains(table.output, "sdf-error at 2000 points")) << table.output;
  EXPECT_TRUE(contains(table.output, "adaptive (")) << table.output;
}

TEST_F(ExperimentCli, AddsAConfigurationFromARunsConfigFile) {
  const fs::path run_dir = *dir_ / "coarse-run";
  const CliRun rec = run_hivox("reconstruct " + kData + kTables +
                               " --levels 1 --voxel-size 0.015 --truncation 0.04 --frames 2 "
                               "--quiet --out " +
                               run_dir.string());
  ASSERT_EQ(rec.exit_code, 0) << rec.output;
  const fs::path exp = *dir_ / "with-config";
  const CliRun r = run_hivox("experiment " + kData + kSmall +
                             " --samples 2000 --tracked never --no-figures --frames 3 --config " +
                             (run_dir / "config.json").string() + " --out " + exp.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json report = nlohmann::json::parse(read_whole_file(exp / "report.json"));
  ASSERT_EQ(report["configs"].size(), 4u);
  EXPECT_EQ(report["configs"][3]["name"], "coarse-run");
  EXPECT_EQ(report["configs"][3]["slug"], "config-coarse-run");
  EXPECT_NEAR(report["configs"][3]["voxel_size_m"].get<double>(), 0.015, 1e-6);
  EXPECT_EQ(report["configs"][3]["levels"].get<int>(), 1);
  // The experiment's frames, not the run's 2.
  EXPECT_EQ(report["configs"][3]["frames_fused"].get<int>(), 3);
}

TEST(ExperimentCliErrors, SayWhatIsWrongInOneLine) {
  test::TempDir tmp;
  struct Case {
    std::string args, says;
  };
  const Case cases[] = {
      {"eval sdf-error", "needs DATASET, or saved maps"},
      {"eval sdf-error --fine " + (tmp / "none.hvx").string() + " --coarse x.hvx", "none.hvx"},
      {"experiment " + kData + " --levels 1 --out " + (tmp / "a").string(), "--levels >= 2"},
      {"experiment " + kData + kSmall + " --reference " + (tmp / "none.ply").string() + " --out " +
           (tmp / "b").string(),
       "none.ply"},
      {"experiment " + kData + kSmall + " --config " + (tmp / "none.json").string() + " --out " +
           (tmp / "c").string(),
       "none.json"},
  };
  for (const Case& c : cases) {
    const CliRun r = run_hivox(c.args + " 2>&1");
    EXPECT_EQ(r.exit_code, 1) << c.args << "\n" << r.output;
    EXPECT_TRUE(contains(r.output, c.says)) << c.args << "\n" << r.output;
    EXPECT_FALSE(contains(r.output, "terminate")) << r.output;
  }
}

}  // namespace
}  // namespace hivox

// Config files: a run writes its effective settings (config.json, also in stats.json), and
// `--config` repeats the run from them, options given on the command line overriding them.

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "apps/cli_util.h"
#include "hivox/io/atomic_file.h"
#include "test_util.h"

namespace hivox {
namespace {

using test::run_hivox;
namespace fs = std::filesystem;

const std::string kScene = "'synthetic:desk?frames=6&width=160&height=120&noise=kinect'";

nlohmann::json read_json(const fs::path& p) {
  return nlohmann::json::parse(read_whole_file(p));
}

TEST(ConfigFile, ARunWritesItsSettingsAndTheConfigRepeatsIt) {
  test::TempDir dir;
  auto r = run_hivox("reconstruct " + kScene +
                     " --poses gt --voxel-size 0.008 --truncation 0.064 --icp-iterations 3,2 "
                     "--no-motion-prior --quiet --out " +
                     (dir / "a").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json config = read_json(dir / "a" / "config.json");
  EXPECT_EQ(config["command"], "reconstruct");
  EXPECT_EQ(config["hivox_version"], "0.1.0");
  const nlohmann::json& o = config["options"];
  EXPECT_DOUBLE_EQ(o["--voxel-size"].get<double>(), 0.008);
  EXPECT_EQ(o["--poses"], "gt");
  EXPECT_EQ(o["--levels"], 3);  // a default, written too
  EXPECT_EQ(o["--icp-iterations"], nlohmann::json::array({3, 2}));
  EXPECT_EQ(o["--no-motion-prior"], true);
  EXPECT_EQ(o["--no-color"], false);
  EXPECT_FALSE(o.contains("--out")) << "where results go is not a setting";
  const nlohmann::json stats = read_json(dir / "a" / "stats.json");
  EXPECT_EQ(stats["hivox_version"], "0.1.0");
  EXPECT_EQ(stats["camera"]["width"], 160);
  EXPECT_TRUE(stats.contains("depth_scale"));
  EXPECT_EQ(stats["config"], config);

  r = run_hivox("reconstruct " + kScene + " --quiet --config " +
                (dir / "a" / "config.json").string() + " --out " + (dir / "b").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(read_whole_file(dir / "a" / "mesh.ply") == read_whole_file(dir / "b" / "mesh.ply"));
  EXPECT_EQ(read_whole_file(dir / "a" / "trajectory.txt"),
            read_whole_file(dir / "b" / "trajectory.txt"));
  EXPECT_EQ(read_json(dir / "b" / "config.json"), config);

  // An option on the command line overrides the file's.
  r = run_hivox("reconstruct " + kScene +
                " --quiet --config=" + (dir / "a" / "config.json").string() +
                " --voxel-size 0.01 --levels 1 --out " + (dir / "c").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json c = read_json(dir / "c" / "config.json")["options"];
  EXPECT_DOUBLE_EQ(c["--voxel-size"].get<double>(), 0.01);
  EXPECT_EQ(c["--levels"], 1);
  EXPECT_DOUBLE_EQ(c["--truncation"].get<double>(), 0.064);
  EXPECT_EQ(read_json(dir / "c" / "stats.json")["levels"], 1);
}

TEST(ConfigFile, BadConfigFilesGetOneClearLine) {
  test::TempDir dir;
  struct Case {
    std::string content, expect;
  };
  const std::vector<Case> cases = {
      {"{oops", "not a valid JSON config file"},
      {"[1, 2]", "a JSON object with \"options\""},
      {R"({"options": {"--voxel-sise": 0.01}})", "has no option --voxel-sise"},
      {R"({"options": {"voxel-size": 0.01}})", "does not start with --"},
      {R"({"command": "demo", "options": {}})", "written by `hivox demo`"},
      {R"({"options": {"--voxel-size": {"a": 1}}})", "is not a number, string, boolean or list"},
      {R"({"options": {"--voxel-size": -1}})", "voxel_size"},
  };
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const fs::path file = dir / fmt::format("c{}.json", i);
    test::write_text(file, cases[i].content);
    const auto r = run_hivox("reconstruct " + kScene + " --quiet --config " + file.string() +
                             " --out " + (dir / "out").string());
    EXPECT_EQ(r.exit_code, 1) << cases[i].content << "\n" << r.output;
    EXPECT_TRUE(test::contains(r.output, cases[i].expect))
        << cases[i].content << ": expected '" << cases[i].expect << "' in\n"
        << r.output;
    EXPECT_LE(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  }
  const auto r = run_hivox("reconstruct " + kScene + " --config " + (dir / "none.json").string());
  EXPECT_TRUE(test::contains(r.output, "none.json: file does not exist")) << r.output;
}

}  // namespace
}  // namespace hivox

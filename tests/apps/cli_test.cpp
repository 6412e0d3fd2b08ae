// The `hivox` program as a user meets it: help text, `info` output, one-line errors, exit codes.

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <string>

#include "../io/dataset_test_util.h"
#include "apps/cli_util.h"

namespace hivox {
namespace {

using test::CliRun;
using test::run_hivox;

std::size_t line_count(const std::string& s) {
  return static_cast<std::size_t>(std::count(s.begin(), s.end(), '\n'));
}

TEST(Cli, InfoHelpIsUsefulToANewcomer) {
  const CliRun r = run_hivox("info --help");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  for (const char* part : {"DATASET", "--preset", "--depth-scale", "--intrinsics", "TUM",
                           "7-Scenes", "InfiniTAM", "tum_fr1", "icl_nuim", "Examples"})
    EXPECT_TRUE(test::contains(r.output, part)) << part << " missing in:\n" << r.output;
  const CliRun top = run_hivox("--help");
  EXPECT_EQ(top.exit_code, 0);
  EXPECT_TRUE(test::contains(top.output, "info")) << top.output;
}

// `hivox devices`: the CPU's line, then a line per CUDA device, or one that says why there is none.
TEST(Cli, DevicesListTheCpuAndSayWhyThereIsNoGpu) {
  const CliRun r = run_hivox("devices");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(r.output.starts_with("cpu ")) << r.output;
  EXPECT_TRUE(test::contains(r.output, " threads (OpenMP)\n") ||
              test::contains(r.output, " thread (OpenMP)\n"))
      << r.output;
  if (test::contains(r.output, "cuda:0 ")) {
    EXPECT_TRUE(test::contains(r.output, "GiB free, compute capability")) << r.output;
  } else {
    // No device: the last line says why and what runs then use.
    EXPECT_TRUE(test::contains(r.output, "\ncuda ")) << r.output;
    EXPECT_TRUE(test::contains(r.output, "runs use --device cpu\n")) << r.output;
  }
  std::size_t gpus = 0;
  for (std::size_t at = r.output.find("\ncuda:"); at != std::string::npos;
       at = r.output.find("\ncuda:", at + 1))
    ++gpus;
  EXPECT_EQ(line_count(r.output), 1 + std::max<std::size_t>(gpus, 1)) << r.output;
}

TEST(Cli, InfoDescribesADataset) {
  test::TempDir dir;
  test::write_small_tum(dir.path());
  const CliRun r = run_hivox("info " + dir.path().string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(test::contains(r.output, "frames:         3")) << r.output;
  EXPECT_TRUE(test::contains(r.output, "ground truth:   yes, 2 of 3")) << r.output;

  const CliRun scaled = run_hivox("info " + dir.path().string() + " --depth-scale 1000");
  EXPECT_EQ(scaled.exit_code, 0) << scaled.output;
  EXPECT_TRUE(test::contains(scaled.output, "depth scale:    1000 raw units per metre  [given]"))
      << scaled.output;

  // Lens distortion from the folder's intrinsics.json: removed unless --keep-distortion.
  test::write_text(dir / "intrinsics.json",
                   R"({"fx": 10, "fy": 10, "cx": 3.5, "cy": 2.5, "width": 8, "height": 6,
                       "distortion_k1k2p1p2k3": [0.1, 0, 0, 0, 0]})");
  const CliRun removed = run_hivox("info " + dir.path().string());
  EXPECT_TRUE(
      test::contains(removed.output, "distortion:     k1=0.1 k2=0 p1=0 p2=0 k3=0  (removed"))
      << removed.output;
  const CliRun kept = run_hivox("info " + dir.path().string() + " --keep-distortion");
  EXPECT_TRUE(test::contains(kept.output, "(kept)")) << kept.output;
}

TEST(Cli, BadInputIsOneLineAndExitCodeOne) {
  test::TempDir dir;
  test::write_small_tum(dir.path());
  const std::string missing = (dir / "missing").string();
  for (const std::string& args :
       {"info " + missing, "info " + dir.path().string() + " --depth-scale 0",
        "info " + dir.path().string() + " --depth-scale -5",
        "info " + dir.path().string() + " --preset nope",
        "info " + dir.path().string() + " --intrinsics " + missing}) {
    const CliRun r = run_hivox(args);
    EXPECT_EQ(r.exit_code, 1) << args << "\n" << r.output;
    EXPECT_EQ(line_count(r.output), 1u) << args << "\n" << r.output;
    EXPECT_TRUE(test::contains(r.output, "[error]")) << r.output;
  }
  EXPECT_TRUE(test::contains(run_hivox("info " + missing).output, "does not exist"));
  EXPECT_TRUE(test::contains(run_hivox("info " + dir.path().string() + " --depth-scale 0").output,
                             "--depth-scale"));
}

TEST(Cli, ViewAndLiveViewServeAndTheirErrorsAreOneLine) {
  test::TempDir dir;
  const std::string out = (dir / "run").string();
  // A short run with the live page: the address is printed even with --quiet.
  const CliRun demo = run_hivox(
      "reconstruct 'synthetic:desk?frames=3&width=80&height=60' --poses gt --view "
      "--quiet --out " +
      out);
  EXPECT_EQ(demo.exit_code, 0) << demo.output;
  EXPECT_TRUE(test::contains(demo.output, "live view: http://127.0.0.1:")) << demo.output;
  // The viewer on that run, for a second.
  const CliRun view = run_hivox("view " + out + " --seconds 0.5");
  EXPECT_EQ(view.exit_code, 0) << view.output;
  EXPECT_TRUE(test::contains(view.output, "viewer: http://127.0.0.1:")) << view.output;
  EXPECT_TRUE(test::contains(view.output, "served 0 requests")) << view.output;
  const std::string missing = (dir / "missing").string();
  for (const auto& [args, words] : std::vector<std::pair<std::string, std::string>>{
           {"view " + missing, missing},
           {"view " + dir.path().string(), "no mesh.ply"},
           {"view " + out + " --address 70000", "70000"},
           {"view " + out + " --address host:port", "host:port"},
           {"view " + out + "/stats.json", "also takes a run's output folder"},
           {"reconstruct 'synthetic:desk?frames=2&width=80&height=60' --view=nowhere:x --out " +
                (dir / "x").string(),
            "nowhere:x"}}) {
    const CliRun r = run_hivox(args);
    EXPECT_EQ(r.exit_code, 1) << args << "\n" << r.output;
    EXPECT_EQ(line_count(r.output), 1u) << args << "\n" << r.output;
    EXPECT_TRUE(test::contains(r.output, words)) << args << "\n" << r.output;
  }
}

}  // namespace
}  // namespace hivox

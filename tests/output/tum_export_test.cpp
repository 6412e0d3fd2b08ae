#include "hivox/output/tum_export.h"

#include <gtest/gtest.h>

#include <fstream>

#include "hivox/core/error.h"
#include "hivox/io/dataset.h"
#include "hivox/io/image_io.h"
#include "hivox/io/intrinsics_io.h"
#include "hivox/io/text_lines.h"
#include "hivox/io/trajectory_io.h"
#include "hivox/synth/synthetic_dataset.h"
#include "test_util.h"

namespace hivox {
namespace {

using test::TempDir;
namespace fs = std::filesystem;

TEST(TumExport, WritesALayoutThatRoundTrips) {
  TempDir dir;
  SyntheticDataset data(parse_synthetic_spec("synthetic:box?frames=4&width=160&height=120"));
  const double scale = 5000;
  std::size_t progress_calls = 0;
  export_tum(data, dir.path(), scale, 3, [&](std::size_t done, std::size_t total) {
    EXPECT_EQ(total, 3u);
    EXPECT_EQ(done, ++progress_calls);
  });
  EXPECT_EQ(progress_calls, 3u);

  const auto assoc = read_text_lines(dir / "associations.txt");
  ASSERT_EQ(assoc.size(), 3u);
  const auto depth_list = read_text_lines(dir / "depth.txt");
  const auto rgb_list = read_text_lines(dir / "rgb.txt");
  ASSERT_EQ(depth_list.size(), 3u);
  ASSERT_EQ(rgb_list.size(), 3u);
  const auto gt = read_tum_trajectory(dir / "groundtruth.txt");
  ASSERT_EQ(gt.size(), 3u);

  for (std::size_t i = 0; i < 3; ++i) {
    const RgbdFrame f = data.read(i);
    // associations: t_rgb rgb/F t_depth depth/F
    ASSERT_EQ(assoc[i].fields.size(), 4u);
    EXPECT_NEAR(std::stod(assoc[i].fields[0]), f.timestamp_s, 1e-6);
    EXPECT_NEAR(std::stod(assoc[i].fields[2]), f.timestamp_s, 1e-6);
    EXPECT_EQ(assoc[i].fields[1], rgb_list[i].fields[1]);
    EXPECT_EQ(assoc[i].fields[3], depth_list[i].fields[1]);

    const DepthImage back = depth_to_metres(read_depth16(dir / assoc[i].fields[3]), scale);
    ASSERT_EQ(back.width(), 160);
    std::size_t valid = 0;
    for (std::size_t k = 0; k < back.size(); ++k) {
      const float d = f.depth_m.data()[k];
      ASSERT_EQ(back.data()[k] > 0.0f, d > 0.0f);
      ASSERT_NEAR(back.data()[k], d, 0.5 / scale + 1e-6);
      valid += d > 0.0f;
    }
    EXPECT_GT(valid, 500u);

    const ColorImage rgb = read_color(dir / assoc[i].fields[1]);
    for (std::size_t k = 0; k < rgb.size(); ++k) ASSERT_EQ(rgb.data()[k], f.color.data()[k]);

    EXPECT_NEAR(gt[i].timestamp_s, f.timestamp_s, 1e-6);
    const Pose& truth = *f.T_wc_gt;
    EXPECT_LT((gt[i].T_wc.translation() - truth.translation()).norm(), 1e-6);
    EXPECT_LT((gt[i].T_wc.linear() - truth.linear()).cwiseAbs().maxCoeff(), 1e-6);
  }

  const IntrinsicsFile intr = read_intrinsics_json(dir / "intrinsics.json");
  EXPECT_FLOAT_EQ(intr.camera.fx, data.camera().fx);
  EXPECT_FLOAT_EQ(intr.camera.cy, data.camera().cy);
  EXPECT_EQ(intr.camera.width, 160);
  EXPECT_DOUBLE_EQ(intr.depth_scale, scale);
}

// A rendered sequence says how noisy its depth is, so that reading it back gives the
// refinement and tracking the right noise model (noise-free depth is not a Kinect's).
TEST(TumExport, TheDepthNoiseModelTravelsWithTheSequence) {
  TempDir dir;
  for (const char* noise : {"none", "kinect"}) {
    SyntheticDataset data(
        parse_synthetic_spec(std::string("synthetic:spheres?frames=2&width=80&noise=") + noise));
    const fs::path seq = dir / noise;
    export_tum(data, seq, 5000);
    const IntrinsicsFile intr = read_intrinsics_json(seq / "intrinsics.json");
    ASSERT_TRUE(intr.depth_noise.has_value()) << noise;
    const auto reader = open_dataset(seq.string());
    const SensorNoise n = reader->info().rig.depth_noise;
    EXPECT_EQ(n.sigma_m(2.0f), data.info().rig.depth_noise.sigma_m(2.0f)) << noise;
    EXPECT_EQ(n.sigma_m(2.0f) == 0.0f, std::string(noise) == "none");
  }
  // Another model is written as numbers; a bad value names the field.
  IntrinsicsFile f = read_intrinsics_json(dir / "none" / "intrinsics.json");
  f.depth_noise = SensorNoise{0.002f, 0.003f, 0.5f};
  write_intrinsics_json(dir / "other.json", f);
  const IntrinsicsFile back = read_intrinsics_json(dir / "other.json");
  ASSERT_TRUE(back.depth_noise.has_value());
  EXPECT_FLOAT_EQ(back.depth_noise->quadratic_per_m, 0.003f);
  test::write_text(dir / "bad.json",
                   R"({"fx": 500, "fy": 500, "cx": 40, "cy": 30, "width": 80, "height": 60, )"
                   R"("depth_noise": "loud"})");
  try {
    read_intrinsics_json(dir / "bad.json");
    FAIL() << "accepted depth_noise \"loud\"";
  } catch (const Error& e) {
    EXPECT_TRUE(test::contains(e.what(), "depth_noise")) << e.what();
  }
}

TEST(TumExport, AllFramesByDefaultAndBadScale) {
  TempDir dir;
  SyntheticDataset data(parse_synthetic_spec("synthetic:spheres?frames=2&width=80&noise=none"));
  export_tum(data, dir / "seq", 1000);
  EXPECT_EQ(read_text_lines(dir / "seq" / "associations.txt").size(), 2u);
  EXPECT_THROW(export_tum(data, dir / "bad", 0.0), Error);
  EXPECT_THROW(export_tum(data, dir / "bad", -5.0), Error);
}

// An export into a folder that holds a sequence already is refused (the two sequences' frames
// would mix), and replaces it as a whole when allowed.
TEST(TumExport, AnExistingSequenceIsReplacedWholeOrNotAtAll) {
  TempDir dir;
  SyntheticDataset four(parse_synthetic_spec("synthetic:box?frames=4&width=80&noise=none"));
  export_tum(four, dir / "seq", 1000);
  SyntheticDataset two(parse_synthetic_spec("synthetic:spheres?frames=2&width=80&noise=none"));
  EXPECT_THROW(export_tum(two, dir / "seq", 1000), Error);
  EXPECT_EQ(read_text_lines(dir / "seq" / "associations.txt").size(), 4u) << "left as it was";
  export_tum(two, dir / "seq", 1000, 0, {}, /*overwrite=*/true);
  EXPECT_EQ(read_text_lines(dir / "seq" / "associations.txt").size(), 2u);
  std::size_t depth_files = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir / "seq" / "depth"))
    ++depth_files;
  EXPECT_EQ(depth_files, 2u) << "no frame of the old sequence is left among the new";
}

TEST(TumExport, UnwritableDirectoryIsAnIoError) {
  TempDir dir;
  test::write_text(dir / "file", "x");
  SyntheticDataset data(parse_synthetic_spec("synthetic:box?frames=1&width=80&noise=none"));
  try {
    export_tum(data, dir / "file" / "seq");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::Io);
    EXPECT_TRUE(test::contains(e.what(), "file")) << e.what();
  }
}

}  // namespace
}  // namespace hivox

// Dataset readers on small datasets the tests write themselves: every layout, the calibration
// rules, and every bad input a reader must name.

#include "hivox/io/dataset.h"

#include <gtest/gtest.h>

#include <cmath>

#include "dataset_test_util.h"
#include "hivox/core/error.h"
#include "hivox/core/undistort.h"
#include "hivox/io/intrinsics_io.h"

namespace hivox {
namespace {

using namespace hivox::test;  // NOLINT: test helpers

constexpr float kTol = 1e-5f;

float tum_metres(int base, int x, int y) {
  return static_cast<float>(base + 10 * x + y) / 5000.0f;
}

// ---- TUM -------------------------------------------------------------------------------------

TEST(TumDataset, AssociationsDepthColourAndGroundTruth) {
  TempDir dir;
  write_small_tum(dir.path());
  ASSERT_EQ(detect_layout(dir.path()), DatasetLayout::Tum);
  auto reader = open_dataset(dir.path().string());
  const DatasetInfo& info = reader->info();
  EXPECT_EQ(info.layout, DatasetLayout::Tum);
  EXPECT_EQ(reader->size(), 3u);
  EXPECT_EQ(info.rig.depth_camera.width, kWidth);
  EXPECT_EQ(info.rig.depth_camera.height, kHeight);
  EXPECT_EQ(info.rig.depth_camera.fx, 10.0f);
  EXPECT_EQ(info.rig.color_camera.fx, 10.0f);
  EXPECT_TRUE(info.rig.T_color_depth.isApprox(Pose::Identity()));
  EXPECT_DOUBLE_EQ(info.first_timestamp_s, 1.00);  // the depth timestamp, not the colour one
  EXPECT_TRUE(info.has_color);
  EXPECT_TRUE(info.has_ground_truth);
  EXPECT_EQ(info.ground_truth_count, 2u);
  EXPECT_EQ(info.rig.depth_scale, 5000.0);
  EXPECT_TRUE(test::contains(info.depth_scale_source, "intrinsics.json"))
      << info.depth_scale_source;
  EXPECT_TRUE(test::contains(info.intrinsics_source, "intrinsics.json")) << info.intrinsics_source;
  EXPECT_TRUE(info.warnings.empty()) << info.warnings.front();

  const RgbdFrame f0 = reader->read(0);
  EXPECT_EQ(f0.index, 0u);
  EXPECT_DOUBLE_EQ(f0.timestamp_s, 1.00);
  ASSERT_TRUE(f0.T_wc_gt.has_value());  // GT at 1.005: 5 ms away
  EXPECT_TRUE(f0.T_wc_gt->translation().isApprox(Eigen::Vector3d(1, 2, 3)));

  const RgbdFrame f1 = reader->read(1);
  ASSERT_EQ(f1.depth_m.width(), kWidth);
  ASSERT_EQ(f1.depth_m.height(), kHeight);
  EXPECT_NEAR(f1.depth_m(3, 2), tum_metres(6000, 3, 2), kTol);
  EXPECT_NEAR(f1.depth_m(7, 5), tum_metres(6000, 7, 5), kTol);
  ASSERT_EQ(f1.color.width(), kWidth);
  EXPECT_EQ(f1.color(3, 2), (Rgb8{1, 30, 20}));
  ASSERT_TRUE(f1.T_wc_gt.has_value());  // GT at 1.119: 19 ms away, nearer than 1.005
  EXPECT_TRUE(f1.T_wc_gt->translation().isApprox(Eigen::Vector3d(4, 5, 6)));
  EXPECT_TRUE((f1.T_wc_gt->linear() * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY()));

  const RgbdFrame f2 = reader->read(2);
  EXPECT_DOUBLE_EQ(f2.timestamp_s, 1.20);
  EXPECT_FALSE(f2.T_wc_gt.has_value());  // nearest GT poses are 21 ms away: none, frame still read
  EXPECT_NEAR(f2.depth_m(0, 0), tum_metres(7000, 0, 0), kTol);
}

TEST(TumDataset, ZeroDepthIsInvalid) {
  TempDir dir;
  write_small_tum(dir.path());
  Image<uint16_t> d = raw_depth(5000);
  d(2, 1) = 0;
  write_depth(dir / "depth/d0.png", d);
  const RgbdFrame f = open_dataset(dir.path().string())->read(0);
  EXPECT_EQ(f.depth_m(2, 1), 0.0f);
  EXPECT_NEAR(f.depth_m(2, 2), tum_metres(5000, 2, 2), kTol);
}

TEST(TumDataset, ReversedAssociationColumns) {
  TempDir dir;
  write_small_tum(dir.path());
  write_text(dir / "associations.txt",
             "1.00 depth/d0.png 0.99 rgb/c0.png\n1.10 depth/d1.png 1.09 rgb/c1.png\n");
  auto reader = open_dataset(dir.path().string());
  ASSERT_EQ(reader->size(), 2u);
  EXPECT_DOUBLE_EQ(reader->info().first_timestamp_s, 1.00);
  const RgbdFrame f = reader->read(1);
  EXPECT_NEAR(f.depth_m(1, 1), tum_metres(6000, 1, 1), kTol);
  EXPECT_EQ(f.color(0, 0).r, 1);
}

TEST(TumDataset, AmbiguousFoldersDecidedByBitDepth) {
  // Both files in one folder: the column whose file is a 16-bit PNG is depth, in either order.
  for (const bool depth_first : {false, true}) {
    TempDir dir;
    write_depth(dir / "frames/a.png", raw_depth(5000));
    write_colour(dir / "frames/b.png", colour(9));
    write_intrinsics(dir / "intrinsics.json", tiny_camera(), 5000.0);
    write_text(dir / "associations.txt", depth_first ? "2.0 frames/a.png 2.01 frames/b.png\n"
                                                     : "2.01 frames/b.png 2.0 frames/a.png\n");
    auto reader = open_dataset(dir.path().string());
    const RgbdFrame f = reader->read(0);
    EXPECT_DOUBLE_EQ(f.timestamp_s, 2.0) << "depth_first=" << depth_first;
    EXPECT_NEAR(f.depth_m(4, 3), tum_metres(5000, 4, 3), kTol);
    EXPECT_EQ(f.color(4, 3).r, 9);
  }
}

TEST(TumDataset, AssociateTimestampsFollowsTumRule) {
  // Greedy by smallest |dt|: (1.012, 1.010) wins, so neither 1.000 nor 1.025 finds a partner
  // (a nearest-neighbour search per depth frame would use 1.012 twice).
  const std::vector<double> rgb = {2.000, 1.100, 1.012, 1.000};
  const std::vector<double> depth = {2.019, 1.300, 1.025, 1.010};
  const auto m = associate_timestamps(rgb, depth);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_EQ(m[0], (std::pair<std::size_t, std::size_t>{2, 3}));  // sorted by time
  EXPECT_EQ(m[1], (std::pair<std::size_t, std::size_t>{0, 0}));
  EXPECT_TRUE(associate_timestamps({1.0}, {1.03}).empty());
  EXPECT_EQ(associate_timestamps({1.0}, {1.03}, 0.05).size(), 1u);
  EXPECT_TRUE(associate_timestamps({}, {1.0}).empty());
}

TEST(TumDataset, RgbAndDepthListsAreAssociated) {
  TempDir dir;
  const char* rgb_times[] = {"1.000", "1.012", "1.100", "2.000"};
  const char* depth_times[] = {"1.010", "1.025", "1.300", "2.019"};
  std::string rgb_txt = "# timestamp filename\n", depth_txt = "# timestamp filename\n";
  for (int i = 3; i >= 0; --i) {  // lists out of order on purpose
    write_colour(dir / fmt::format("rgb/{}.png", rgb_times[i]), colour(static_cast<uint8_t>(i)));
    write_depth(dir / fmt::format("depth/{}.png", depth_times[i]),
                raw_depth(static_cast<uint16_t>(5000 + 1000 * i)));
    rgb_txt += fmt::format("{0} rgb/{0}.png\n", rgb_times[i]);
    depth_txt += fmt::format("{0} depth/{0}.png\n", depth_times[i]);
  }
  write_text(dir / "rgb.txt", rgb_txt);
  write_text(dir / "depth.txt", depth_txt);
  write_intrinsics(dir / "intrinsics.json", tiny_camera(), 5000.0);
  auto reader = open_dataset(dir.path().string());
  ASSERT_EQ(reader->size(), 2u);
  const RgbdFrame f0 = reader->read(0);
  EXPECT_DOUBLE_EQ(f0.timestamp_s, 1.010);
  EXPECT_NEAR(f0.depth_m(0, 0), tum_metres(5000, 0, 0), kTol);  // depth 1.010
  EXPECT_EQ(f0.color(0, 0).r, 1);                               // colour 1.012
  const RgbdFrame f1 = reader->read(1);
  EXPECT_DOUBLE_EQ(f1.timestamp_s, 2.019);
  EXPECT_EQ(f1.color(0, 0).r, 3);
  EXPECT_FALSE(reader->info().has_ground_truth);
}

TEST(TumDataset, DepthListWithoutColour) {
  TempDir dir;
  write_depth(dir / "depth/b.png", raw_depth(6000));
  write_depth(dir / "depth/a.png", raw_depth(5000));
  write_text(dir / "depth.txt", "2.0 depth/b.png\n1.0 depth/a.png\n");
  write_intrinsics(dir / "intrinsics.json", tiny_camera(), 5000.0);
  auto reader = open_dataset(dir.path().string());
  ASSERT_EQ(reader->size(), 2u);
  EXPECT_FALSE(reader->info().has_color);
  const RgbdFrame f = reader->read(0);
  EXPECT_DOUBLE_EQ(f.timestamp_s, 1.0);
  EXPECT_TRUE(f.color.empty());
  EXPECT_NEAR(f.depth_m(0, 0), 1.0f, kTol);
}

TEST(TumDataset, MaxFramesTruncates) {
  TempDir dir;
  write_small_tum(dir.path());
  DatasetParams params;
  params.max_frames = 1;
  auto reader = open_dataset(dir.path().string(), params);
  EXPECT_EQ(reader->size(), 1u);
  EXPECT_EQ(reader->info().ground_truth_count, 1u);
  expect_error([&] { reader->read(1); }, ErrorCode::InvalidArgument, {"frame index 1"});
}

// ---- intrinsics and depth scale --------------------------------------------------------------

/// One 640x480 frame (the presets' size) in a TUM folder `name` below `root`.
std::filesystem::path write_vga_tum(const std::filesystem::path& root, const std::string& name) {
  const auto dir = root / name;
  write_depth(dir / "depth/0.png", raw_depth(9000, 640, 480));
  write_colour(dir / "rgb/0.png", colour(0, 640, 480));
  write_text(dir / "associations.txt", "0 rgb/0.png 0 depth/0.png\n");
  return dir;
}

TEST(DatasetCalibration, GuessedFromFolderName) {
  TempDir root;
  const auto dir = write_vga_tum(root.path(), "rgbd_dataset_freiburg2_desk");
  auto reader = open_dataset(dir.string());
  const DatasetInfo& info = reader->info();
  EXPECT_EQ(info.rig.depth_camera.fx, 520.9f);
  EXPECT_EQ(info.rig.depth_camera.cy, 249.7f);
  EXPECT_TRUE(test::contains(info.intrinsics_source, "tum_fr2")) << info.intrinsics_source;
  EXPECT_TRUE(test::contains(info.intrinsics_source, "guessed")) << info.intrinsics_source;
  EXPECT_EQ(info.rig.depth_scale, 5000.0);
  // At the principal point the fr2 lens distortion (removed on reading) moves nothing.
  EXPECT_NEAR(reader->read(0).depth_m(325, 250), (9000.0f + 3250 + 250) / 5000.0f, kTol);

  const auto fr1 = write_vga_tum(root.path(), "fr1_xyz");
  EXPECT_EQ(open_dataset(fr1.string())->info().rig.depth_camera.fx, 517.3f);
}

TEST(DatasetCalibration, LensDistortionIsRemovedAsFramesAreRead) {
  TempDir root;
  const auto dir = write_vga_tum(root.path(), "set");
  IntrinsicsFile file;
  file.camera = {500, 500, 320, 240, 640, 480};
  file.depth_scale = 5000;
  file.distortion = {0.2f, -0.5f, 0.001f, -0.002f, 0.3f};
  write_intrinsics_json(dir / "intrinsics.json", file);
  EXPECT_EQ(read_intrinsics_json(dir / "intrinsics.json").distortion.k3, 0.3f);  // round trip

  auto reader = open_dataset(dir.string());
  const DatasetInfo& info = reader->info();
  EXPECT_TRUE(info.undistorted);
  EXPECT_EQ(info.distortion.k1, 0.2f);
  EXPECT_EQ(info.distortion.p2, -0.002f);
  EXPECT_TRUE(test::contains(describe_dataset(*reader), "removed from every frame"));
  DatasetParams keep;
  keep.undistort = false;
  auto raw_reader = open_dataset(dir.string(), keep);
  EXPECT_FALSE(raw_reader->info().undistorted);
  const RgbdFrame raw = raw_reader->read(0), frame = reader->read(0);
  const Undistorter undistorter(file.camera, file.distortion);
  const DepthImage expected_depth = undistorter.depth(raw.depth_m);
  const ColorImage expected_colour = undistorter.color(raw.color);
  int moved = 0;
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x) {
      ASSERT_EQ(frame.depth_m(x, y), expected_depth(x, y)) << x << "," << y;
      ASSERT_EQ(frame.color(x, y), expected_colour(x, y)) << x << "," << y;
      moved += frame.depth_m(x, y) != raw.depth_m(x, y);
    }
  EXPECT_GT(moved, 640 * 480 / 2);  // every pixel value differs here: most moved

  // The TUM presets carry the published distortion; a guessed fr1 folder is undistorted too.
  const auto fr1 = write_vga_tum(root.path(), "fr1_xyz");
  const DatasetInfo fr1_info = open_dataset(fr1.string())->info();
  EXPECT_TRUE(fr1_info.undistorted);
  EXPECT_EQ(fr1_info.distortion.k1, 0.2624f);
  // 4 coefficients (k3 = 0) are accepted, as OpenCV writes them.
  write_text(dir / "intrinsics.json",
             R"({"fx": 500, "fy": 500, "cx": 320, "cy": 240, "width": 640, "height": 480,
                 "distortion_k1k2p1p2k3": [0.1, 0.01, 0, 0]})");
  EXPECT_EQ(open_dataset(dir.string())->info().distortion.k1, 0.1f);
}

TEST(DatasetCalibration, NothingToGoOnAsksForPresetOrIntrinsics) {
  TempDir root;
  const auto dir = write_vga_tum(root.path(), "mystery");
  expect_error([&] { open_dataset(dir.string()); }, ErrorCode::InvalidArgument,
               {"mystery", "--preset", "--intrinsics", "tum_fr1"});
}

TEST(DatasetCalibration, ExplicitChoicesBeatTheFolder) {
  TempDir root;
  const auto dir = write_vga_tum(root.path(), "set");
  PinholeCamera folder_camera{500, 500, 320, 240, 640, 480};
  write_intrinsics(dir / "intrinsics.json", folder_camera, 1000.0);

  // Folder only.
  EXPECT_EQ(open_dataset(dir.string())->info().rig.depth_camera.fx, 500.0f);

  // Preset: intrinsics and depth scale from the preset; ICL-NUIM's negative fy is legal.
  DatasetParams params;
  params.preset = "icl_nuim";
  auto icl = open_dataset(dir.string(), params);
  EXPECT_EQ(icl->info().rig.depth_camera.fy, -480.0f);
  EXPECT_EQ(icl->info().rig.depth_scale, 5000.0);
  EXPECT_TRUE(test::contains(icl->info().depth_scale_source, "icl_nuim"));
  EXPECT_NEAR(icl->read(0).depth_m(0, 0), 9000.0f / 5000.0f, kTol);

  // An intrinsics file without a depth scale: camera from it, scale still from the folder.
  PinholeCamera other{600, 601, 320, 240, 640, 480};
  write_intrinsics(root / "other.json", other, 0.0);
  params = {};
  params.intrinsics_path = root / "other.json";
  auto given = open_dataset(dir.string(), params);
  EXPECT_EQ(given->info().rig.depth_camera.fy, 601.0f);
  EXPECT_TRUE(test::contains(given->info().intrinsics_source, "other.json"));
  EXPECT_EQ(given->info().rig.depth_scale, 1000.0);
  EXPECT_TRUE(test::contains(given->info().depth_scale_source, "set"));

  // A depth scale override beats everything.
  params = {};
  params.depth_scale = 2500;
  auto scaled = open_dataset(dir.string(), params);
  EXPECT_EQ(scaled->info().rig.depth_scale, 2500.0);
  EXPECT_EQ(scaled->info().depth_scale_source, "given");
  EXPECT_NEAR(scaled->read(0).depth_m(0, 0), 9000.0f / 2500.0f, kTol);
}

TEST(DatasetCalibration, TumDefaultDepthScaleWhenFileHasNone) {
  TempDir dir;
  write_small_tum(dir.path());
  write_intrinsics(dir / "intrinsics.json", tiny_camera(), 0.0);
  auto reader = open_dataset(dir.path().string());
  EXPECT_EQ(reader->info().rig.depth_scale, 5000.0);
  EXPECT_TRUE(test::contains(reader->info().depth_scale_source, "TUM default"));
}

TEST(DatasetCalibration, PresetTable) {
  EXPECT_EQ(camera_preset("tum_fr1").camera.fx, 517.3f);
  EXPECT_EQ(camera_preset("tum_fr3").camera.fy, 539.2f);
  EXPECT_EQ(camera_preset("tum_default").camera.cx, 319.5f);
  EXPECT_EQ(camera_preset("icl_nuim").camera.fy, -480.0f);
  EXPECT_EQ(camera_preset("seven_scenes").depth_scale, 1000.0);
  EXPECT_EQ(camera_preset("tum_fr2").depth_scale, 5000.0);
  for (const CameraPreset& p : camera_presets()) {
    EXPECT_EQ(p.camera.width, 640) << p.name;
    EXPECT_EQ(p.camera.height, 480) << p.name;
    EXPECT_NO_THROW(p.camera.validate(std::string(p.name)));
  }
  expect_error([] { camera_preset("tum_fr4"); }, ErrorCode::InvalidArgument,
               {"tum_fr4", "tum_fr1", "icl_nuim", "seven_scenes"});
}

TEST(DatasetCalibration, ImplausibleDepthScaleIsAWarning) {
  // Millimetre depth (0.4 m) labelled as TUM's 5000: the median comes out at 0.08 m.
  TempDir dir;
  write_small_tum(dir.path());
  for (int i = 0; i < 3; ++i) write_depth(dir / fmt::format("depth/d{}.png", i), raw_depth(400));
  auto reader = open_dataset(dir.path().string());
  ASSERT_EQ(reader->info().warnings.size(), 1u);
  const std::string& w = reader->info().warnings[0];
  EXPECT_TRUE(test::contains(w, "depth scale 5000")) << w;
  EXPECT_TRUE(test::contains(w, "--depth-scale 1000")) << w;
  // Frames still read, in the scale asked for.
  EXPECT_NEAR(reader->read(0).depth_m(0, 0), 400.0f / 5000.0f, kTol);
}

TEST(DatasetCalibration, FramesFarApartInTimeAreAWarning) {
  // Keyframes half a second apart: tracking cannot follow, and says nothing itself.
  TempDir dir;
  write_small_tum(dir.path());
  write_text(dir / "associations.txt",
             "0.99 rgb/c0.png 1.00 depth/d0.png\n"
             "1.49 rgb/c1.png 1.50 depth/d1.png\n"
             "2.09 rgb/c2.png 2.10 depth/d2.png\n");
  auto reader = open_dataset(dir.path().string());
  EXPECT_DOUBLE_EQ(reader->info().median_frame_step_s, 0.6);
  ASSERT_EQ(reader->info().warnings.size(), 1u);
  const std::string& w = reader->info().warnings[0];
  for (const char* part : {"frames are 0.60 s apart", "1.7 frames/s", "--poses gt"})
    EXPECT_TRUE(test::contains(w, part)) << "'" << part << "' missing in: " << w;
  EXPECT_TRUE(test::contains(describe_dataset(*reader), "frame step:     0.600 s median"));
  // The first two frames only: one step of 0.5 s.
  DatasetParams first_two;
  first_two.max_frames = 2;
  EXPECT_DOUBLE_EQ(open_dataset(dir.path().string(), first_two)->info().median_frame_step_s, 0.5);
  // 0.1 s apart (the small set's own timestamps): no warning.
  write_small_tum(dir.path());
  EXPECT_TRUE(open_dataset(dir.path().string())->info().warnings.empty());
}

TEST(DatasetCalibration, DescribeSaysWhatWasFound) {
  TempDir dir;
  write_small_tum(dir.path());
  auto reader = open_dataset(dir.path().string());
  const std::string text = describe_dataset(*reader);
  for (const char* part :
       {"layout:         TUM", "frames:         3", "resolution:     8x6", "fx=10.000",
        "depth scale:    5000", "1.000 / ", "/ 1.415 m", "colour:         yes",
        "ground truth:   yes, 2 of 3 frames", "first time:     1.000000 s",
        "frame step:     0.100 s median (10.0 frames/s)", "warnings:       none"})
    EXPECT_TRUE(test::contains(text, part)) << "'" << part << "' missing in:\n" << text;
}

TEST(DatasetParams, ValidateAndPrint) {
  DatasetParams p;
  EXPECT_NO_THROW(p.validate());
  EXPECT_TRUE(test::contains(p.to_string(), "depth_scale=auto")) << p.to_string();
  p.depth_scale = -1;
  expect_error([&] { p.validate(); }, ErrorCode::InvalidArgument, {"depth_scale", "-1"});
  p.depth_scale = std::nan("");
  expect_error([&] { p.validate(); }, ErrorCode::InvalidArgument, {"depth_scale"});
  p.depth_scale = 1000;
  p.preset = "kinect";
  expect_error([&] { p.validate(); }, ErrorCode::InvalidArgument, {"kinect", "tum_fr1"});
  p.preset = "tum_fr1";
  p.intrinsics_path = "cam.json";
  expect_error([&] { p.validate(); }, ErrorCode::InvalidArgument, {"tum_fr1", "cam.json"});
  p.intrinsics_path.clear();
  p.max_frames = 7;
  p.undistort = false;
  EXPECT_EQ(p.to_string(),
            "preset=tum_fr1 depth_scale=1000 intrinsics=(dataset) max_frames=7 undistort=false");
}

// ---- 7-Scenes --------------------------------------------------------------------------------

/// Pose of frame i: rotation 0.1 i rad about x, translation (i, 2 i, 3 i).
Pose seven_scenes_pose(int i) {
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(0.1 * i, Eigen::Vector3d::UnitX()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(i, 2 * i, 3 * i);
  return T;
}

void write_pose_file(const std::filesystem::path& path, const Pose& T) {
  std::string text;  // tab-separated with a trailing tab, like the real files
  const Eigen::Matrix4d m = T.matrix();
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) text += fmt::format(" {:.9e}\t", m(r, c));
    text += "\n";
  }
  write_text(path, text);
}

/// scene/seq-01 with frames 0-2, scene/seq-02 with frames 0-1 (no pose for its frame 1).
/// Depth raw 2000 + 100 k (mm) with one 65535 pixel; small camera from the scene's json.
void write_seven_scenes(const std::filesystem::path& scene) {
  int k = 0;
  for (const auto& [seq, count] : {std::pair{"seq-01", 3}, std::pair{"seq-02", 2}}) {
    for (int i = 0; i < count; ++i, ++k) {
      const auto stem = scene / seq / fmt::format("frame-{:06d}", i);
      Image<uint16_t> d = raw_depth(static_cast<uint16_t>(2000 + 100 * k));
      d(0, 0) = 65535;
      write_depth(stem.string() + ".depth.png", d);
      write_colour(stem.string() + ".color.png", colour(static_cast<uint8_t>(k)));
      if (k != 4) write_pose_file(stem.string() + ".pose.txt", seven_scenes_pose(k));
    }
  }
  write_text(scene / "seq-01/notes.txt", "not a frame\n");
  write_intrinsics(scene / "intrinsics.json", tiny_camera(), 0.0);  // no scale: preset's 1000
}

TEST(SevenScenesDataset, SequencesFramesAndPoses) {
  TempDir dir;
  write_seven_scenes(dir.path());
  ASSERT_EQ(detect_layout(dir.path()), DatasetLayout::SevenScenes);
  auto reader = open_dataset(dir.path().string());
  const DatasetInfo& info = reader->info();
  EXPECT_EQ(info.layout, DatasetLayout::SevenScenes);
  ASSERT_EQ(reader->size(), 5u);
  EXPECT_EQ(info.rig.depth_scale, 1000.0);
  EXPECT_TRUE(test::contains(info.depth_scale_source, "seven_scenes")) << info.depth_scale_source;
  EXPECT_TRUE(test::contains(info.intrinsics_source, "intrinsics.json")) << info.intrinsics_source;
  EXPECT_EQ(info.ground_truth_count, 4u);
  EXPECT_TRUE(info.has_color);
  EXPECT_DOUBLE_EQ(info.first_timestamp_s, 0.0);
  // Numbered frames: no recorded timestamps, so no step to judge.
  EXPECT_FALSE(info.timestamps_recorded);
  EXPECT_EQ(info.median_frame_step_s, 0.0);
  ASSERT_EQ(info.warnings.size(), 1u);
  EXPECT_TRUE(test::contains(info.warnings[0], "registered")) << info.warnings[0];

  const RgbdFrame f3 = reader->read(3);  // seq-02, frame 0: timestamps keep increasing
  EXPECT_DOUBLE_EQ(f3.timestamp_s, 3.0 / 30.0);
  EXPECT_EQ(f3.depth_m(0, 0), 0.0f);  // 65535 = invalid
  EXPECT_NEAR(f3.depth_m(5, 4), (2300 + 50 + 4) / 1000.0f, kTol);
  EXPECT_EQ(f3.color(1, 1), (Rgb8{3, 10, 10}));
  ASSERT_TRUE(f3.T_wc_gt.has_value());
  EXPECT_TRUE(f3.T_wc_gt->isApprox(seven_scenes_pose(3), 1e-9));
  const RgbdFrame f2 = reader->read(2);
  ASSERT_TRUE(f2.T_wc_gt.has_value());
  EXPECT_TRUE(f2.T_wc_gt->isApprox(seven_scenes_pose(2), 1e-9));
  EXPECT_FALSE(reader->read(4).T_wc_gt.has_value());

  // One sequence folder on its own.
  auto seq = open_dataset((dir / "seq-02").string());
  EXPECT_EQ(seq->size(), 2u);
  EXPECT_EQ(seq->info().rig.depth_camera.fx, 585.0f);  // no json there: the 7-Scenes preset
}

TEST(SevenScenesDataset, MalformedPoseFilesNameTheFile) {
  TempDir dir;
  write_seven_scenes(dir.path());
  auto reader = open_dataset(dir.path().string());
  const auto pose = dir / "seq-01/frame-000001.pose.txt";
  write_text(pose, "1 0 0 0\n0 1 0 x\n0 0 1 0\n0 0 0 1\n");
  expect_error([&] { reader->read(1); }, ErrorCode::InvalidData,
               {"frame-000001.pose.txt:2", "'x'"});
  write_text(pose, "1 0 0 0\n0 1 0 0\n0 0 1 0\n");
  expect_error([&] { reader->read(1); }, ErrorCode::InvalidData,
               {"frame-000001.pose.txt", "16 numbers", "found 12"});
  write_text(pose, "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 1 1\n");
  expect_error([&] { reader->read(1); }, ErrorCode::InvalidData,
               {"frame-000001.pose.txt", "0 0 0 1"});
  write_text(pose, "2 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
  expect_error([&] { reader->read(1); }, ErrorCode::InvalidData,
               {"frame-000001.pose.txt", "rotation"});
}

TEST(SevenScenesDataset, MillimetreScaleOnTumDepthWarns) {
  TempDir dir;
  write_seven_scenes(dir.path());
  for (const char* f : {"seq-01/frame-000000", "seq-01/frame-000001", "seq-01/frame-000002",
                        "seq-02/frame-000000", "seq-02/frame-000001"})
    write_depth(dir / (std::string(f) + ".depth.png"), raw_depth(12000));  // 2.4 m at 5000
  auto reader = open_dataset(dir.path().string());
  ASSERT_EQ(reader->info().warnings.size(), 2u);
  EXPECT_TRUE(test::contains(reader->info().warnings[1], "--depth-scale 5000"))
      << reader->info().warnings[1];
}

// ---- InfiniTAM -------------------------------------------------------------------------------

std::string calib_text(const std::string& depth_line,
                       const std::string& extrinsics = "1 0 0 0.025\n0 1 0 0\n0 0 1 0\n") {
  return "8 6\n12 12\n4 3\n\n8 6\n10 10\n3.5 2.5\n\n" + extrinsics + "\n" + depth_line + "\n";
}

TEST(InfiniTamDataset, CalibAndPgmPpmFrames) {
  TempDir dir;
  // Colour camera 0.1 m along the depth camera's x, rotated 90 degrees about z.
  write_text(dir / "calib.txt", calib_text("affine 0.0002 0", "0 -1 0 0.1\n1 0 0 0\n0 0 1 0\n"));
  for (int i = 0; i < 3; ++i) {
    write_pgm16(dir / fmt::format("Frames/{:04d}.pgm", i),
                raw_depth(static_cast<uint16_t>(5000 + 1000 * i)));
    write_ppm(dir / fmt::format("Frames/{:04d}.ppm", i), colour(static_cast<uint8_t>(i)));
  }
  ASSERT_EQ(detect_layout(dir.path()), DatasetLayout::InfiniTam);
  auto reader = open_dataset(dir.path().string());
  const DatasetInfo& info = reader->info();
  EXPECT_EQ(info.layout, DatasetLayout::InfiniTam);
  ASSERT_EQ(reader->size(), 3u);
  EXPECT_EQ(info.rig.depth_camera.fx, 10.0f);
  EXPECT_EQ(info.rig.color_camera.fx, 12.0f);
  EXPECT_EQ(info.rig.color_camera.cx, 4.0f);
  EXPECT_DOUBLE_EQ(info.rig.depth_scale, 5000.0);
  EXPECT_TRUE(test::contains(info.depth_scale_source, "affine")) << info.depth_scale_source;
  EXPECT_FALSE(info.has_ground_truth);
  EXPECT_TRUE(info.warnings.empty());
  // calib.txt maps colour-camera points into the depth camera: the colour camera's centre sits
  // at (0.1, 0, 0) in the depth frame, so T_color_depth maps that point to the origin.
  EXPECT_TRUE((info.rig.T_color_depth * Eigen::Vector3d(0.1, 0, 0)).isZero(1e-9));
  EXPECT_TRUE((info.rig.T_color_depth.linear() * Eigen::Vector3d::UnitY())
                  .isApprox(Eigen::Vector3d::UnitX(), 1e-9));
  const RgbdFrame f = reader->read(2);
  EXPECT_DOUBLE_EQ(f.timestamp_s, 2.0 / 30.0);
  EXPECT_NEAR(f.depth_m(6, 4), (7000 + 60 + 4) * 0.0002f, kTol);
  EXPECT_EQ(f.color(6, 4), (Rgb8{2, 60, 40}));
  const std::string text = describe_dataset(*reader);
  EXPECT_TRUE(test::contains(text, "T_color_depth")) << text;
}

TEST(InfiniTamDataset, PngFramesWithPrefixesPaddingAndOffset) {
  TempDir dir;
  write_text(dir / "calib.txt", calib_text("affine 0.001 -0.05"));
  for (int i = 0; i < 2; ++i) {
    Image<uint16_t> d = raw_depth(static_cast<uint16_t>(1000 + 500 * i));
    d(0, 0) = 30;  // 0.03 m - 0.05 m < 0: invalid
    write_depth(dir / fmt::format("depth_{:05d}.png", i), d);
    write_colour(dir / fmt::format("color_{:05d}.png", i), colour(static_cast<uint8_t>(i)));
  }
  auto reader = open_dataset(dir.path().string());
  ASSERT_EQ(reader->size(), 2u);
  EXPECT_DOUBLE_EQ(reader->info().rig.depth_scale, 1000.0);
  const RgbdFrame f = reader->read(1);
  EXPECT_NEAR(f.depth_m(2, 1), (1500 + 20 + 1) * 0.001f - 0.05f, kTol);
  EXPECT_EQ(f.depth_m(0, 0), 0.0f);
  EXPECT_EQ(f.color(0, 0).r, 1);
}

TEST(InfiniTamDataset, BareZeroDisparityLineMeansMillimetres) {
  TempDir dir;
  write_text(dir / "calib.txt", calib_text("0 0"));
  write_pgm16(dir / "0.pgm", raw_depth(1500));
  auto reader = open_dataset(dir.path().string());
  EXPECT_DOUBLE_EQ(reader->info().rig.depth_scale, 1000.0);
  EXPECT_FALSE(reader->info().has_color);
  EXPECT_NEAR(reader->read(0).depth_m(0, 0), 1.5f, kTol);
}

TEST(InfiniTamDataset, BadCalibration) {
  TempDir dir;
  write_pgm16(dir / "0000.pgm", raw_depth(1500));
  write_text(dir / "calib.txt", calib_text("kinect 1135.09 0.0819141"));
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::Unsupported,
               {"calib.txt:13", "disparity", "affine"});
  write_text(dir / "calib.txt", calib_text("1135.09 0.0819141"));
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::Unsupported,
               {"calib.txt:13", "disparity"});
  write_text(dir / "calib.txt", calib_text("affine 0 0.1"));
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidData,
               {"calib.txt:13", "affine a"});
  write_text(dir / "calib.txt", "640 480\n500 500\n320 240\n");
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidData,
               {"calib.txt", "affine a b"});
  write_text(dir / "calib.txt",
             "8 6\n12 12\n4 3\n\n8 6\n0 10\n3.5 2.5\n\n1 0 0 0\n0 1 0 0\n0 0 1 0\n\naffine 1 0\n");
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidArgument,
               {"calib.txt:5", "depth", "fx"});
  write_text(dir / "calib.txt", calib_text("affine 0.001 0", "1 0 0\n0 1 0 0\n0 0 1 0\n"));
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidData,
               {"calib.txt:9", "found 3"});
}

TEST(InfiniTamDataset, MissingColourFrameOrNoFrames) {
  TempDir dir;
  write_text(dir / "calib.txt", calib_text("affine 0.001 0"));
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidData,
               {"no numbered depth frames"});
  write_pgm16(dir / "0000.pgm", raw_depth(1500));
  write_pgm16(dir / "0001.pgm", raw_depth(1500));
  write_ppm(dir / "0000.ppm", colour(0));
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidData,
               {"0001.pgm", "no colour image", "####.ppm"});
}

// ---- bad input -------------------------------------------------------------------------------

TEST(DatasetBadInput, MissingOrWrongDirectory) {
  TempDir dir;
  const std::string missing = (dir / "no_such_set").string();
  expect_error([&] { open_dataset(missing); }, ErrorCode::Io, {missing, "does not exist"});
  expect_error([&] { detect_layout(missing); }, ErrorCode::Io, {missing});
  write_text(dir / "file.txt", "x");
  expect_error([&] { open_dataset((dir / "file.txt").string()); }, ErrorCode::Io,
               {"file.txt", "not a directory"});
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidData,
               {dir.path().string(), "associations.txt", "calib.txt", "frame-NNNNNN.depth.png"});
  expect_error([&] { open_dataset(""); }, ErrorCode::InvalidArgument, {"empty"});
  expect_error([&] { open_dataset("synthetic:nosuchscene"); }, ErrorCode::InvalidArgument,
               {"nosuchscene"});
  DatasetParams with_preset;
  with_preset.preset = "tum_fr1";
  expect_error([&] { open_dataset("synthetic:desk", with_preset); }, ErrorCode::InvalidArgument,
               {"synthetic:desk", "--preset"});
}

TEST(Dataset, SyntheticSpecsOpenBuiltInScenes) {
  DatasetParams params;
  params.max_frames = 7;
  const auto reader = open_dataset("synthetic:box?frames=20&width=80&height=60&noise=none", params);
  EXPECT_EQ(reader->info().layout, DatasetLayout::Synthetic);
  EXPECT_EQ(reader->size(), 7u);
  EXPECT_EQ(reader->info().rig.depth_camera.width, 80);
  const RgbdFrame f = reader->read(3);
  EXPECT_TRUE(f.T_wc_gt.has_value());
  EXPECT_EQ(f.depth_m.width(), 80);
}

TEST(DatasetBadInput, MissingImages) {
  TempDir dir;
  write_small_tum(dir.path());
  std::filesystem::remove(dir / "depth/d1.png");
  std::filesystem::remove(dir / "rgb/c2.png");
  auto reader = open_dataset(dir.path().string());
  expect_error([&] { reader->read(1); }, ErrorCode::Io, {"d1.png", "does not exist"});
  expect_error([&] { reader->read(2); }, ErrorCode::Io, {"c2.png", "does not exist"});
  EXPECT_NO_THROW(reader->read(0));
}

TEST(DatasetBadInput, UnreadableOrWrongKindOfDepth) {
  TempDir dir;
  write_small_tum(dir.path());
  auto reader = open_dataset(dir.path().string());
  write_text(dir / "depth/d0.png", "not a png at all");
  expect_error([&] { reader->read(0); }, ErrorCode::InvalidData, {"d0.png"});
  write_png(dir / "depth/d0.png", Image<uint8_t>(kWidth, kHeight, 7));
  expect_error([&] { reader->read(0); }, ErrorCode::InvalidData, {"d0.png", "8-bit"});
  write_png(dir / "depth/d0.png", colour(1));
  expect_error([&] { reader->read(0); }, ErrorCode::InvalidData, {"d0.png", "colour"});
  write_text(dir / "rgb/c1.png", "garbage");
  expect_error([&] { reader->read(1); }, ErrorCode::InvalidData, {"c1.png"});
}

TEST(DatasetBadInput, WrongImageSize) {
  TempDir dir;
  write_small_tum(dir.path());
  write_depth(dir / "depth/d1.png", raw_depth(5000, 10, 6));
  write_colour(dir / "rgb/c2.png", colour(0, 8, 7));
  auto reader = open_dataset(dir.path().string());
  expect_error([&] { reader->read(1); }, ErrorCode::InvalidData,
               {"d1.png", "depth", "10x6", "8x6", "intrinsics.json"});
  expect_error([&] { reader->read(2); }, ErrorCode::InvalidData, {"c2.png", "8x7", "8x6"});
}

TEST(DatasetBadInput, BrokenFirstFrameStillOpensWithAWarning) {
  TempDir dir;
  write_small_tum(dir.path());
  std::filesystem::remove(dir / "depth/d0.png");
  auto reader = open_dataset(dir.path().string());
  ASSERT_EQ(reader->info().warnings.size(), 1u);
  EXPECT_TRUE(test::contains(reader->info().warnings[0], "d0.png"));
}

TEST(DatasetBadInput, AssociationLists) {
  TempDir dir;
  write_small_tum(dir.path());
  write_text(dir / "associations.txt", "# only a comment\n\n");
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidData,
               {"associations.txt", "empty"});
  write_text(dir / "associations.txt",
             "0.99 rgb/c0.png 1.00 depth/d0.png\n1.09 rgb/c1.png 1.10 depth/d1.png\n"
             "1.19 rgb/c2.png 1.20\n");
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidData,
               {"associations.txt:3", "found 3"});
  write_text(dir / "associations.txt",
             "0.99 rgb/c0.png 1.00 depth/d0.png\n1.09 rgb/c1.png 1.1O depth/d1.png\n");
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidData,
               {"associations.txt:2", "depth timestamp", "1.1O"});
  write_text(dir / "associations.txt", "1 a/x.png 2 b/y.png\n");
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::Io,
               {"associations.txt:1", "x.png", "do not exist"});
}

TEST(DatasetBadInput, RgbDepthLists) {
  TempDir dir;
  write_intrinsics(dir / "intrinsics.json", tiny_camera(), 5000.0);
  write_text(dir / "depth.txt", "# nothing\n");
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidData,
               {"depth.txt", "lists no images"});
  write_text(dir / "depth.txt", "1.0 depth/a.png\n2.0\n");
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidData,
               {"depth.txt:2", "timestamp filename"});
  write_text(dir / "depth.txt", "1.0 depth/a.png\n");
  write_text(dir / "rgb.txt", "# c\nabc rgb/a.png\n");
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidData,
               {"rgb.txt:2", "timestamp"});
  write_text(dir / "rgb.txt", "5.0 rgb/a.png\n");
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidData,
               {"rgb.txt", "depth.txt", "no colour/depth pair"});
}

TEST(DatasetBadInput, MalformedGroundTruth) {
  TempDir dir;
  write_small_tum(dir.path());
  write_text(dir / "groundtruth.txt", "# header\n1.0 0 0 0 0 0 0 1\n1.1 0 0 0 0 0 1\n");
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidData,
               {"groundtruth.txt:3", "8 values"});
  write_text(dir / "groundtruth.txt", "5.0 0 0 0 0 0 0 1\n");
  auto reader = open_dataset(dir.path().string());
  EXPECT_FALSE(reader->info().has_ground_truth);
  ASSERT_EQ(reader->info().warnings.size(), 1u);
  EXPECT_TRUE(test::contains(reader->info().warnings[0], "groundtruth.txt"));
}

TEST(DatasetBadInput, BadIntrinsics) {
  TempDir dir;
  write_small_tum(dir.path());
  const auto json = dir / "intrinsics.json";
  const std::string rest = R"("cx": 3.5, "cy": 2.5, "width": 8, "height": 6)";
  write_text(json, R"({"fx": 0, "fy": 10, )" + rest + "}");
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidArgument,
               {"intrinsics.json", "fx"});
  write_text(json, R"({"fx": -10, "fy": 10, )" + rest + "}");
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidArgument,
               {"intrinsics.json", "fx", "-10"});
  write_text(json, R"({"fx": 10, "fy": 0, )" + rest + "}");
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidArgument,
               {"intrinsics.json", "fy"});
  write_text(json, R"({"fx": 10, "fy": 10, "depth_scale": 0, )" + rest + "}");
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidArgument,
               {"intrinsics.json", "depth_scale"});
  write_text(json, R"({"fx": 10, "fy": 10, "depth_scale": -5000, )" + rest + "}");
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidArgument,
               {"intrinsics.json", "depth_scale", "-5000"});
  write_text(json, R"({"fx": 10, "fy": 10, "cx": 3.5})");
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidData,
               {"intrinsics.json", "cy"});
  write_text(json,
             R"({"fx": 10, "fy": 10, "distortion_k1k2p1p2k3": [0.1, 0.2, 0.3], )" + rest + "}");
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidData,
               {"intrinsics.json", "distortion_k1k2p1p2k3", "4 or 5"});
  write_text(json, R"({"fx": 10, "fy": 10, "distortion_k1k2p1p2k3": "none", )" + rest + "}");
  expect_error([&] { open_dataset(dir.path().string()); }, ErrorCode::InvalidData,
               {"intrinsics.json", "distortion_k1k2p1p2k3"});
  // A broken folder file does not matter when the user gives the intrinsics.
  DatasetParams params;
  params.intrinsics_path = dir / "given.json";
  write_intrinsics(params.intrinsics_path, tiny_camera(), 5000.0);
  EXPECT_EQ(open_dataset(dir.path().string(), params)->size(), 3u);
  params.intrinsics_path = dir / "absent.json";
  expect_error([&] { open_dataset(dir.path().string(), params); }, ErrorCode::Io, {"absent.json"});
}

TEST(DatasetBadInput, BadDepthScaleParameter) {
  TempDir dir;
  write_small_tum(dir.path());
  DatasetParams params;
  params.depth_scale = -1000;
  expect_error([&] { open_dataset(dir.path().string(), params); }, ErrorCode::InvalidArgument,
               {"depth_scale", "-1000"});
  params.depth_scale = 0;
  params.preset = "tum_fr9";
  expect_error([&] { open_dataset(dir.path().string(), params); }, ErrorCode::InvalidArgument,
               {"tum_fr9"});
}

}  // namespace
}  // namespace hivox

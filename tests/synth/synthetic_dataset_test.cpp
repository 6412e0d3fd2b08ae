#include "hivox/synth/synthetic_dataset.h"

#include <gtest/gtest.h>

#include "hivox/core/error.h"
#include "test_util.h"

namespace hivox {
namespace {

std::string error_of(std::string_view spec) {
  try {
    parse_synthetic_spec(spec);
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::InvalidArgument);
    return e.what();
  }
  return "";
}

TEST(SyntheticSpec, Parses) {
  SyntheticParams p = parse_synthetic_spec("synthetic:desk");
  EXPECT_EQ(p.scene, "desk");
  EXPECT_EQ(p.frames, 300u);
  EXPECT_EQ(p.width, 640);
  EXPECT_TRUE(p.noise.enabled());
  const PinholeCamera c = p.effective_camera();
  EXPECT_FLOAT_EQ(c.fx, 525.0f);
  EXPECT_FLOAT_EQ(c.fy, 525.0f);
  EXPECT_FLOAT_EQ(c.cx, 319.5f);
  EXPECT_FLOAT_EQ(c.cy, 239.5f);

  p = parse_synthetic_spec("synthetic:keyboard?frames=100&noise=none&width=320&height=240");
  EXPECT_EQ(p.scene, "keyboard");
  EXPECT_EQ(p.frames, 100u);
  EXPECT_FALSE(p.noise.enabled());
  EXPECT_EQ(p.effective_camera().width, 320);
  EXPECT_FLOAT_EQ(p.effective_camera().fx, 262.5f);
  EXPECT_FLOAT_EQ(p.effective_camera().cy, 119.5f);

  p = parse_synthetic_spec("synthetic:room?seed=42&noise=kinect&width=160&max_depth=4.5&fps=15");
  EXPECT_EQ(p.noise.seed, 42u);  // kept although `noise=` comes later
  EXPECT_EQ(p.height, 120);      // 4:3 from the width alone
  EXPECT_DOUBLE_EQ(p.max_depth_m, 4.5);
  EXPECT_DOUBLE_EQ(p.fps, 15.0);
  EXPECT_TRUE(is_synthetic_spec("synthetic:blob"));
  EXPECT_FALSE(is_synthetic_spec("/data/tum_fr1"));
}

TEST(SyntheticSpec, BadSpecsNameTheProblem) {
  std::string e = error_of("synthetic:kitchen");
  EXPECT_TRUE(test::contains(e, "kitchen")) << e;
  EXPECT_TRUE(test::contains(e, "desk")) << e;
  e = error_of("synthetic:desk?frames=ten");
  EXPECT_TRUE(test::contains(e, "frames")) << e;
  e = error_of("synthetic:desk?frames=0");
  EXPECT_TRUE(test::contains(e, "frames")) << e;
  e = error_of("synthetic:desk?colour=1");
  EXPECT_TRUE(test::contains(e, "unknown key 'colour'")) << e;
  e = error_of("synthetic:desk?noise=heavy");
  EXPECT_TRUE(test::contains(e, "heavy")) << e;
  e = error_of("synthetic:desk?width");
  EXPECT_TRUE(test::contains(e, "KEY=VALUE")) << e;
  e = error_of("synthetic:desk?width=-5");
  EXPECT_TRUE(test::contains(e, "width")) << e;
  e = error_of("synthetic:");
  EXPECT_TRUE(test::contains(e, "scene name")) << e;
  e = error_of("desk");
  EXPECT_TRUE(test::contains(e, "synthetic:")) << e;
}

TEST(SyntheticParams, ValidateNamesTheField) {
  SyntheticParams p;
  p.camera = PinholeCamera{500, 500, 319.5, 239.5, 320, 240};
  EXPECT_THROW(p.validate(), Error);  // camera size differs from width x height
  p.width = 320;
  p.height = 240;
  EXPECT_NO_THROW(p.validate());
  p.max_depth_m = -1;
  try {
    p.validate();
    FAIL();
  } catch (const Error& e) {
    EXPECT_TRUE(test::contains(e.what(), "max_depth_m")) << e.what();
  }
  EXPECT_TRUE(test::contains(SyntheticParams{}.to_string(), "desk"));
}

TEST(SyntheticDataset, ReadsFramesWithGroundTruth) {
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=5&width=160&height=120"));
  const DatasetInfo& info = data.info();
  EXPECT_EQ(info.source, "synthetic:desk");
  EXPECT_EQ(info.layout, DatasetLayout::Synthetic);
  EXPECT_EQ(info.frame_count, 5u);
  EXPECT_EQ(data.size(), 5u);
  EXPECT_EQ(info.rig.depth_scale, 0.0);
  EXPECT_TRUE(info.has_color);
  EXPECT_TRUE(info.has_ground_truth);
  EXPECT_EQ(info.rig.depth_camera.width, 160);
  EXPECT_EQ(data.trajectory().size(), 5u);

  const RgbdFrame f = data.read(3);
  EXPECT_EQ(f.index, 3u);
  EXPECT_DOUBLE_EQ(f.timestamp_s, 0.1);
  ASSERT_TRUE(f.T_wc_gt);
  EXPECT_TRUE(f.T_wc_gt->isApprox(data.trajectory()[3].T_wc));
  EXPECT_EQ(f.depth_m.width(), 160);
  EXPECT_EQ(f.color.height(), 120);
  // Kinect noise by default: close to, but not equal to, the clean depth.
  const RenderedFrame clean = data.render_clean(3);
  int differ = 0, close = 0, valid = 0;
  for (std::size_t i = 0; i < f.depth_m.size(); ++i) {
    const float d = f.depth_m.data()[i], c = clean.depth_m.data()[i];
    if (d <= 0) continue;
    ++valid;
    differ += d != c;
    close += std::abs(d - c) < 0.05f;
  }
  EXPECT_GT(valid, 0.9 * f.depth_m.size());
  EXPECT_GT(differ, 0.5 * valid);
  EXPECT_GT(close, 0.95 * valid);
  // Deterministic: reading again gives the same frame.
  const RgbdFrame again = data.read(3);
  for (std::size_t i = 0; i < f.depth_m.size(); ++i)
    ASSERT_EQ(f.depth_m.data()[i], again.depth_m.data()[i]);
  EXPECT_THROW(data.read(5), Error);
}

TEST(SyntheticDataset, NoiseFreeDepthIsTheExactRender) {
  SyntheticDataset data(parse_synthetic_spec("synthetic:spheres?frames=4&width=160&noise=none"));
  const RgbdFrame f = data.read(1);
  const RenderedFrame clean = data.render_clean(1);
  for (std::size_t i = 0; i < f.depth_m.size(); ++i)
    ASSERT_EQ(f.depth_m.data()[i], clean.depth_m.data()[i]);
  // Every valid pixel back-projects onto the scene's surface (exact SDF ~ 0 there).
  const PinholeCamera& cam = data.camera();
  const Pose& T = *f.T_wc_gt;
  int checked = 0;
  for (int v = 0; v < cam.height; v += 3)
    for (int u = 0; u < cam.width; u += 3) {
      const float z = f.depth_m(u, v);
      if (z <= 0) continue;
      const Eigen::Vector3d p_c((u - cam.cx) / cam.fx * z, (v - cam.cy) / cam.fy * z, z);
      ASSERT_NEAR(data.scene().sdf(T * p_c), 0.0, 1e-5);
      ++checked;
    }
  EXPECT_GT(checked, 50);
}

TEST(SyntheticDataset, DeclaresItsDepthNoise) {
  const SyntheticDataset clean(parse_synthetic_spec("synthetic:spheres?frames=2&noise=none"));
  EXPECT_EQ(clean.info().rig.depth_noise.sigma_m(0.5f), 0.0f);
  EXPECT_EQ(clean.info().rig.depth_noise.sigma_m(3.0f), 0.0f);
  const SyntheticDataset noisy(parse_synthetic_spec("synthetic:spheres?frames=2&noise=kinect"));
  const NoiseParams kinect = NoiseParams::kinect();
  for (const float z : {0.5f, 1.0f, 2.0f, 3.5f})
    EXPECT_NEAR(noisy.info().rig.depth_noise.sigma_m(z), kinect.axial_sigma_m(z), 1e-7) << z;
}

}  // namespace
}  // namespace hivox

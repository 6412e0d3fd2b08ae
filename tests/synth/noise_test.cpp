#include "hivox/synth/noise.h"

#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "hivox/core/error.h"
#include "hivox/core/threads.h"
#include "test_util.h"

namespace hivox {
namespace {

using Vec3 = Eigen::Vector3d;

PinholeCamera camera_320() {
  return {262.5f, 262.5f, 159.5f, 119.5f, 320, 240};
}

RenderedFrame fronto_parallel_plane(double z_m, const PinholeCamera& cam) {
  SyntheticScene scene;
  scene.add(Plane{Vec3(0, 0, z_m), -Vec3::UnitZ()});
  return render(scene, cam, Pose::Identity());
}

struct Stats {
  double mean = 0, sigma = 0;
  std::size_t valid = 0, total = 0;
};

// Statistics of (noisy - clean) over the central half of the image, over several frames.
Stats noise_stats(const RenderedFrame& clean, const PinholeCamera& cam, const NoiseParams& p,
                  int frames) {
  double s = 0, s2 = 0;
  Stats out;
  for (int f = 0; f < frames; ++f) {
    const DepthImage noisy = apply_noise(clean, cam, p, f);
    for (int v = cam.height / 4; v < 3 * cam.height / 4; ++v)
      for (int u = cam.width / 4; u < 3 * cam.width / 4; ++u) {
        ++out.total;
        if (noisy(u, v) <= 0.0f) continue;
        const double e = static_cast<double>(noisy(u, v)) - clean.depth_m(u, v);
        s += e;
        s2 += e * e;
        ++out.valid;
      }
  }
  out.mean = s / out.valid;
  out.sigma = std::sqrt(s2 / out.valid - out.mean * out.mean);
  return out;
}

TEST(Noise, KinectDefaultsAreNguyen2012) {
  const NoiseParams p;
  EXPECT_NEAR(p.axial_sigma_m(0.4), 0.0012, 1e-12);
  EXPECT_NEAR(p.axial_sigma_m(1.0), 0.0012 + 0.0019 * 0.36, 1e-12);
  EXPECT_NEAR(p.axial_sigma_m(2.5), 0.0012 + 0.0019 * 2.1 * 2.1, 1e-12);
  EXPECT_GT(p.axial_sigma_m(1.0, 1.2), p.axial_sigma_m(1.0, 0.2));   // grows at grazing angles
  EXPECT_NEAR(p.depth_step_m(1.0), 0.125 / (0.075 * 580.0), 1e-12);  // ~2.9 mm at 1 m
  EXPECT_TRUE(p.enabled());
  EXPECT_FALSE(NoiseParams::none().enabled());
  EXPECT_NO_THROW(p.validate());
}

// The empirical axial sigma (Gaussian + disparity quantisation) matches sigma_z(z).
TEST(Noise, AxialSigmaMatchesModel) {
  const PinholeCamera cam = camera_320();
  NoiseParams p;
  p.dropout_probability = 0;
  for (double z : {1.0, 1.5, 2.5}) {
    const RenderedFrame clean = fronto_parallel_plane(z, cam);
    const Stats s = noise_stats(clean, cam, p, 4);
    const double expected = p.axial_sigma_m(z);
    EXPECT_NEAR(s.sigma / expected, 1.0, 0.1)
        << "z=" << z << " sigma=" << s.sigma << " expected " << expected;
    EXPECT_LT(std::abs(s.mean), 0.1 * expected) << "z=" << z << " bias " << s.mean;
    EXPECT_EQ(s.valid, s.total) << "a fronto-parallel plane loses no pixels";
  }
}

TEST(Noise, DepthLiesOnDisparityLevels) {
  const PinholeCamera cam = camera_320();
  const NoiseParams p;
  const double bf = p.baseline_m * p.disparity_focal_px;
  for (double z : {1.0, 2.5}) {
    const DepthImage noisy = apply_noise(fronto_parallel_plane(z, cam), cam, p, 0);
    std::set<long> levels;
    for (std::size_t i = 0; i < noisy.size(); ++i) {
      const double d = noisy.data()[i];
      if (d <= 0) continue;
      const double level = bf / (d * p.disparity_step_px);
      ASSERT_NEAR(level, std::round(level), 2e-3) << "depth " << d << " is between levels";
      levels.insert(std::lround(level));
    }
    // Neighbouring levels near z are one depth step apart; a few sigma wide spread of levels.
    const double spread_levels = 8 * p.axial_sigma_m(z) / p.depth_step_m(z);
    EXPECT_GE(levels.size(), 3u);
    EXPECT_LE(static_cast<double>(levels.size()), spread_levels + 3) << "z=" << z;
    const double step = p.depth_step_m(z);
    EXPECT_NEAR(bf / (*levels.begin() * p.disparity_step_px) -
                    bf / ((*levels.begin() + 1) * p.disparity_step_px),
                step, 0.2 * step);
  }
}

TEST(Noise, GrazingAnglesAreInvalid) {
  const PinholeCamera cam = camera_320();
  NoiseParams p;
  p.dropout_probability = 0;
  p.edge_dropout_probability = 0;
  // A plane whose normal is 70 degrees away from the optical axis: across the image the
  // incidence angle runs from ~40 to past 90 degrees.
  const double a = 70.0 * M_PI / 180.0;
  SyntheticScene scene;
  scene.add(Plane{Vec3(0, 0, 1.5), Vec3(std::sin(a), 0, -std::cos(a))});
  const RenderedFrame clean = render(scene, cam, Pose::Identity());
  const DepthImage noisy = apply_noise(clean, cam, p, 3);
  std::size_t low = 0, low_valid = 0, high = 0, high_valid = 0;
  for (int v = 0; v < cam.height; ++v)
    for (int u = 0; u < cam.width; ++u) {
      if (clean.depth_m(u, v) <= 0.0f) continue;
      const Vec3 ray = Vec3((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1).normalized();
      const Vec3f n = clean.normal_w(u, v);
      const double theta = std::acos(-(ray.x() * n.x + ray.y() * n.y + ray.z() * n.z));
      if (theta < p.max_incidence_rad - 0.1) {
        ++low;
        low_valid += noisy(u, v) > 0.0f;
      } else if (theta > p.max_incidence_rad + 0.05) {
        ++high;
        high_valid += noisy(u, v) > 0.0f;
      }
    }
  ASSERT_GT(low, 1000u);
  ASSERT_GT(high, 1000u);
  EXPECT_GT(static_cast<double>(low_valid) / low, 0.99);
  EXPECT_LT(static_cast<double>(high_valid) / high, 0.01);
}

TEST(Noise, FrontoParallelHasFewInvalidPixels) {
  const PinholeCamera cam = camera_320();
  const NoiseParams p;  // with its default random dropout
  const Stats s = noise_stats(fronto_parallel_plane(1.2, cam), cam, p, 2);
  const double invalid = 1.0 - static_cast<double>(s.valid) / s.total;
  EXPECT_LT(invalid, 0.005);
  EXPECT_NEAR(invalid, p.dropout_probability, 0.001);
}

TEST(Noise, NearLimitInvalidates) {
  const PinholeCamera cam = camera_320();
  const NoiseParams p;
  const DepthImage noisy = apply_noise(fronto_parallel_plane(0.3, cam), cam, p, 0);
  for (std::size_t i = 0; i < noisy.size(); ++i) ASSERT_EQ(noisy.data()[i], 0.0f);
}

// Lateral noise: a pixel beside a depth edge reads the other side with the probability that
// its Gaussian lookup offset crosses the edge.
TEST(Noise, LateralJitterMatchesSigma) {
  const PinholeCamera cam{131.25f, 131.25f, 79.5f, 59.5f, 160, 120};
  SyntheticScene scene;
  // Near face (z = 1) left of x = 0, i.e. columns <= 79; far plane (z = 2) elsewhere.
  scene.add(Box{Vec3(-5, 0, 1.25), Vec3(5, 5, 0.25)});
  scene.add(Plane{Vec3(0, 0, 2), -Vec3::UnitZ()});
  const RenderedFrame clean = render(scene, cam, Pose::Identity());
  ASSERT_NEAR(clean.depth_m(79, 60), 1.0f, 1e-6);
  ASSERT_NEAR(clean.depth_m(80, 60), 2.0f, 1e-6);
  NoiseParams p;
  p.dropout_probability = 0;
  p.edge_dropout_probability = 0;
  int crossed79 = 0, crossed80 = 0, crossed78 = 0, n = 0;
  for (int f = 0; f < 25; ++f) {
    const DepthImage noisy = apply_noise(clean, cam, p, f);
    for (int v = 2; v < cam.height - 2; ++v) {
      crossed78 += noisy(78, v) > 1.5f;
      crossed79 += noisy(79, v) > 1.5f;
      crossed80 += noisy(80, v) > 0.0f && noisy(80, v) < 1.5f;
      ++n;
    }
  }
  // P(offset >= 0.5 px) and P(offset >= 1.5 px) for a Gaussian of lateral_sigma_px.
  const double p1 = 0.5 * std::erfc(0.5 / (p.lateral_sigma_px * std::sqrt(2.0)));
  const double p2 = 0.5 * std::erfc(1.5 / (p.lateral_sigma_px * std::sqrt(2.0)));
  EXPECT_NEAR(static_cast<double>(crossed79) / n, p1, 0.03);
  EXPECT_NEAR(static_cast<double>(crossed80) / n, p1, 0.03);
  EXPECT_NEAR(static_cast<double>(crossed78) / n, p2, 0.015);
}

TEST(Noise, DeterministicPerSeedAndFrame) {
  SyntheticScene scene;
  scene.add(Sphere{Vec3(0, 0, 1.5), 0.4});
  scene.add(Plane{Vec3(0, 0, 2.5), -Vec3::UnitZ()});
  const PinholeCamera cam{131.25f, 131.25f, 79.5f, 59.5f, 160, 120};
  const RenderedFrame clean = render(scene, cam, Pose::Identity());
  NoiseParams p;
  auto same = [](const DepthImage& a, const DepthImage& b) {
    for (std::size_t i = 0; i < a.size(); ++i)
      if (a.data()[i] != b.data()[i]) return false;
    return true;
  };
  const DepthImage a = apply_noise(clean, cam, p, 5);
  set_thread_count(1);
  const DepthImage b = apply_noise(clean, cam, p, 5);
  set_thread_count(0);
  EXPECT_TRUE(same(a, b)) << "same seed and frame, different thread count";
  EXPECT_FALSE(same(a, apply_noise(clean, cam, p, 6))) << "another frame";
  p.seed = 2;
  EXPECT_FALSE(same(a, apply_noise(clean, cam, p, 5))) << "another seed";
  EXPECT_TRUE(same(clean.depth_m, apply_noise(clean, cam, NoiseParams::none(), 5)));
}

TEST(Noise, PresetsAndValidation) {
  EXPECT_TRUE(noise_preset("kinect").enabled());
  EXPECT_FALSE(noise_preset("none").enabled());
  try {
    noise_preset("kinect2");
    FAIL();
  } catch (const Error& e) {
    EXPECT_TRUE(test::contains(e.what(), "kinect, none")) << e.what();
  }
  auto message = [](NoiseParams p) -> std::string {
    try {
      p.validate();
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  };
  NoiseParams p;
  p.lateral_sigma_px = -1;
  EXPECT_TRUE(test::contains(message(p), "lateral_sigma_px"));
  p = {};
  p.dropout_probability = 1.5;
  EXPECT_TRUE(test::contains(message(p), "dropout_probability"));
  p = {};
  p.max_incidence_rad = 2.0;
  EXPECT_TRUE(test::contains(message(p), "max_incidence_rad"));
  p = {};
  p.disparity_focal_px = 0;
  EXPECT_TRUE(test::contains(message(p), "disparity_focal_px"));
  // Image and camera must agree.
  const PinholeCamera cam{131.25f, 131.25f, 79.5f, 59.5f, 160, 120};
  const RenderedFrame clean = fronto_parallel_plane(1.0, cam);
  EXPECT_THROW(apply_noise(clean, camera_320(), NoiseParams{}, 0), Error);
}

}  // namespace
}  // namespace hivox

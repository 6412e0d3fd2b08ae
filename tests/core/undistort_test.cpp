// Lens distortion and the undistorting resampler, against a tilted plane imaged through the
// distortion: the distorted image is made by inverting the model independently (Newton), the
// resampler only uses the forward model.

#include "hivox/core/undistort.h"

#include <gtest/gtest.h>

#include <cmath>

#include <Eigen/Dense>

#include "hivox/core/error.h"
#include "test_util.h"

namespace hivox {
namespace {

const LensDistortion kFr1{0.2624f, -0.9531f, -0.0054f, 0.0026f, 1.1633f};  // TUM fr1
const LensDistortion kBarrel{0.25f, 0.0f, 0.002f, -0.001f, 0.0f};  // stronger: pixels move more

TEST(LensDistortion, MatchesTheBrownConradyFormula) {
  // Radial only: r' = r (1 + k1 r^2 + k2 r^4 + k3 r^6).
  const LensDistortion radial{0.1f, 0.01f, 0.0f, 0.0f, 0.001f};
  const Vec2f p = radial.distort({0.3f, -0.4f});  // r^2 = 0.25
  const float scale = 1.0f + 0.1f * 0.25f + 0.01f * 0.0625f + 0.001f * 0.015625f;
  EXPECT_NEAR(p.x, 0.3f * scale, 1e-7f);
  EXPECT_NEAR(p.y, -0.4f * scale, 1e-7f);
  // Tangential only: dx = 2 p1 x y + p2 (r^2 + 2 x^2), dy = p1 (r^2 + 2 y^2) + 2 p2 x y.
  const LensDistortion tangential{0.0f, 0.0f, 0.01f, -0.02f, 0.0f};
  const Vec2f q = tangential.distort({0.3f, -0.4f});
  EXPECT_NEAR(q.x, 0.3f + 2 * 0.01f * 0.3f * -0.4f - 0.02f * (0.25f + 2 * 0.09f), 1e-7f);
  EXPECT_NEAR(q.y, -0.4f + 0.01f * (0.25f + 2 * 0.16f) + 2 * -0.02f * 0.3f * -0.4f, 1e-7f);
  EXPECT_TRUE(LensDistortion{}.none());
  EXPECT_FALSE(kFr1.none());
  const LensDistortion bad{0.1f, NAN, 0, 0, 0};
  try {
    bad.validate("calib.json");
    FAIL() << "a NaN coefficient was accepted";
  } catch (const Error& e) {
    EXPECT_TRUE(test::contains(e.what(), "calib.json")) << e.what();
    EXPECT_TRUE(test::contains(e.what(), "k2")) << e.what();
  }
}

// The ideal normalised point that `d` distorts to `xy_d`, by Newton's method on the model.
Eigen::Vector2d undistort_point(const LensDistortion& d, const Eigen::Vector2d& xy_d) {
  auto f = [&](const Eigen::Vector2d& p) {
    const Vec2f q = d.distort({static_cast<float>(p.x()), static_cast<float>(p.y())});
    return Eigen::Vector2d(q.x, q.y);
  };
  Eigen::Vector2d p = xy_d;
  for (int i = 0; i < 30; ++i) {
    const double h = 1e-4;
    Eigen::Matrix2d J;
    J.col(0) = (f(p + Eigen::Vector2d(h, 0)) - f(p - Eigen::Vector2d(h, 0))) / (2 * h);
    J.col(1) = (f(p + Eigen::Vector2d(0, h)) - f(p - Eigen::Vector2d(0, h))) / (2 * h);
    p -= J.inverse() * (f(p) - xy_d);
  }
  return p;
}

TEST(Undistorter, RecoversTheIdealImageOfATiltedPlane) {
  const PinholeCamera cam{150.0f, 150.0f, 79.5f, 59.5f, 160, 120};
  // Plane through (0, 0, 1.5) with normal n: depth z = 1.5 n_z / (n . (x, y, 1)).
  const Eigen::Vector3d n = Eigen::Vector3d(0.3, -0.2, 1.0).normalized();
  auto plane_depth = [&](const Eigen::Vector2d& xy) {
    return 1.5 * n.z() / n.dot(Eigen::Vector3d(xy.x(), xy.y(), 1.0));
  };
  DepthImage distorted(cam.width, cam.height);
  for (int v = 0; v < cam.height; ++v)
    for (int u = 0; u < cam.width; ++u) {
      const Eigen::Vector2d xy_d((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy);
      distorted(u, v) = static_cast<float>(plane_depth(undistort_point(kBarrel, xy_d)));
    }
  const Undistorter undistorter(cam, kBarrel);
  const DepthImage ideal = undistorter.depth(distorted);
  int valid = 0, invalid = 0, wrong = 0, raw_off = 0;
  for (int v = 0; v < cam.height; ++v)
    for (int u = 0; u < cam.width; ++u) {
      auto truth = [&](double uu, double vv) {
        return plane_depth({(uu - cam.cx) / cam.fx, (vv - cam.cy) / cam.fy});
      };
      // Nearest-pixel sampling is off by at most ~0.71 source pixels (a source pixel is at most
      // ~1.3 ideal pixels here): the tolerance is that much of the local depth change.
      const double step = std::max(std::abs(truth(u + 1, v) - truth(u, v)),
                                   std::abs(truth(u, v + 1) - truth(u, v)));
      const double tol = 0.71 * 1.3 * step + 1e-5;
      raw_off += std::abs(distorted(u, v) - truth(u, v)) > 3 * tol;
      if (ideal(u, v) == 0.0f) {
        ++invalid;
        continue;
      }
      ++valid;
      wrong += std::abs(ideal(u, v) - truth(u, v)) > tol;
    }
  EXPECT_EQ(wrong, 0) << "undistorted depth departs from the ideal plane";
  EXPECT_GT(raw_off, cam.width * cam.height / 5) << "the test distortion is too weak to tell";
  EXPECT_EQ(invalid, undistorter.outside_pixels());
  EXPECT_GT(valid, cam.width * cam.height * 8 / 10);
}

TEST(Undistorter, ColourIsInterpolatedAtTheDistortedPosition) {
  const PinholeCamera cam{150.0f, 150.0f, 79.5f, 59.5f, 160, 120};
  ColorImage ramp(cam.width, cam.height);  // r = x, g = y of the distorted image
  for (int v = 0; v < cam.height; ++v)
    for (int u = 0; u < cam.width; ++u)
      ramp(u, v) = {static_cast<uint8_t>(u), static_cast<uint8_t>(v), 7};
  const Undistorter undistorter(cam, kFr1);
  const ColorImage out = undistorter.color(ramp);
  int checked = 0;
  for (int v = 0; v < cam.height; v += 3)
    for (int u = 0; u < cam.width; u += 3) {
      const Eigen::Vector2d xy((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy);
      const Vec2f d = kFr1.distort({static_cast<float>(xy.x()), static_cast<float>(xy.y())});
      const double su = cam.fx * d.x + cam.cx, sv = cam.fy * d.y + cam.cy;
      if (su < 0 || sv < 0 || su > cam.width - 1 || sv > cam.height - 1) continue;
      EXPECT_NEAR(out(u, v).r, su, 0.51) << u << "," << v;
      EXPECT_NEAR(out(u, v).g, sv, 0.51) << u << "," << v;
      EXPECT_EQ(out(u, v).b, 7);
      ++checked;
    }
  EXPECT_GT(checked, 1500);
}

TEST(Undistorter, NoDistortionIsTheIdentityAndSizesAreChecked) {
  const PinholeCamera cam{150.0f, 150.0f, 79.5f, 59.5f, 160, 120};
  DepthImage depth(cam.width, cam.height);
  for (int i = 0; i < static_cast<int>(depth.size()); ++i) depth.data()[i] = 0.5f + 0.001f * i;
  const Undistorter identity(cam, LensDistortion{});
  const DepthImage same = identity.depth(depth);
  for (std::size_t i = 0; i < depth.size(); ++i) ASSERT_EQ(same.data()[i], depth.data()[i]);
  EXPECT_EQ(identity.outside_pixels(), 0);
  try {
    identity.depth(DepthImage(80, 60));
    FAIL() << "a wrong image size was accepted";
  } catch (const Error& e) {
    EXPECT_TRUE(test::contains(e.what(), "80x60")) << e.what();
  }
}

}  // namespace
}  // namespace hivox

// The per-pixel ICP math: robust weights against their definitions, and one pixel's
// point-to-plane term against values worked out by hand, with each reason a pair is rejected.

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "track/track_kernels.h"

namespace hivox {
namespace {

using kernels::IcpPass;
using kernels::IcpTerm;

TEST(RobustWeight, EachLossAtWorkedResiduals) {
  const float k = 2.0f;
  // {residual in sigmas, Huber (1 up to k, k / |r| beyond), Tukey ((1 - (r / k)^2)^2 up to k)}
  const float cases[][3] = {{0.0f, 1.0f, 1.0f},   {1.0f, 1.0f, 0.5625f},    {-1.0f, 1.0f, 0.5625f},
                            {2.0f, 1.0f, 0.0f},   {4.0f, 0.5f, 0.0f},       {-8.0f, 0.25f, 0.0f},
                            {40.0f, 0.05f, 0.0f}, {0.5f, 1.0f, 0.87890625f}};
  for (const auto& c : cases) {
    EXPECT_EQ(kernels::robust_weight(c[0], RobustLoss::None, k), 1.0f) << c[0];
    EXPECT_FLOAT_EQ(kernels::robust_weight(c[0], RobustLoss::Huber, k), c[1]) << c[0];
    EXPECT_FLOAT_EQ(kernels::robust_weight(c[0], RobustLoss::Tukey, k), c[2]) << c[0];
  }
}

// A model camera looking down +z from the origin, the frame at the same pose, and a model whose
// every pixel holds the plane z = 1 facing the camera.
struct Scene {
  PinholeCamera camera;
  TrackParams params;
  std::vector<Vec3f> points, normals;

  Scene() {
    camera.fx = camera.fy = 100.0;
    camera.cx = 15.5;
    camera.cy = 11.5;
    camera.width = 32;
    camera.height = 24;
    params.noise = SensorNoise::none();
    for (int v = 0; v < camera.height; ++v)
      for (int u = 0; u < camera.width; ++u) {
        points.push_back(camera.unproject(static_cast<float>(u), static_cast<float>(v), 1.0f));
        normals.push_back({0.0f, 0.0f, -1.0f});
      }
  }
  IcpPass pass(const Rigid3f& T_wc) const {
    return IcpPass(T_wc, Rigid3f{Mat3f{}, {0, 0, 0}}, camera, 0.05f, params);
  }
  // The pixel's term as the tracker computes it: its model pixel, then the pair.
  IcpTerm term(const IcpPass& c, const Vec3f& p_c, const Vec3f& n_c) const {
    const Vec3f p_w = c.T_wc * p_c;
    int32_t i = -1;
    const bool inside = kernels::icp_model_pixel(c, p_w, &i);
    const auto k = static_cast<std::size_t>(i);
    return kernels::icp_pair_term(c, p_c, n_c, p_w, inside, points[k], normals[k]);
  }
};

Rigid3f translation(const Vec3f& t) {
  return {Mat3f{}, t};
}

TEST(IcpTerm, PointBehindThePlaneGivesItsDistanceAndJacobian) {
  const Scene s;
  // The camera 1 cm back along z: a point 1.02 m in front of it lies 1 cm behind the plane.
  const IcpPass c = s.pass(translation({0.0f, 0.0f, -0.01f}));
  const Vec3f p_c{0.1f, -0.05f, 1.02f};
  const IcpTerm t = s.term(c, p_c, {0.0f, 0.0f, -1.0f});
  ASSERT_TRUE(t.paired);
  const Vec3f p_w{0.1f, -0.05f, 1.01f};
  // r = n . (p - q) with n = -z: the point is 1 cm beyond the plane, against the normal.
  EXPECT_NEAR(t.r, -0.01f, 1e-6f);
  EXPECT_EQ(t.J.t.x, 0.0f);
  EXPECT_EQ(t.J.t.y, 0.0f);
  EXPECT_EQ(t.J.t.z, -1.0f);
  const Vec3f lever = p_w - c.T_wc.t;  // (p - c) x n
  EXPECT_NEAR(t.J.w.x, -lever.y, 1e-6f);
  EXPECT_NEAR(t.J.w.y, lever.x, 1e-6f);
  EXPECT_NEAR(t.J.w.z, 0.0f, 1e-6f);
  EXPECT_NEAR(t.distance_m, norm(lever), 1e-6f);
  // No sensor noise: sigma is the residual floor, and 1 cm is beyond Huber's 2 sigmas.
  const float sigma = s.params.residual_floor_m;
  const float huber = s.params.robust_scale * sigma / 0.01f;
  EXPECT_NEAR(t.sqrt_weight, std::sqrt(huber) / sigma, 1e-3f * std::sqrt(huber) / sigma);
}

TEST(IcpTerm, RejectsEachMissingOrDistantPair) {
  Scene s;
  const IcpPass c = s.pass(translation({0.0f, 0.0f, 0.0f}));
  const Vec3f n{0.0f, 0.0f, -1.0f};
  EXPECT_TRUE(s.term(c, {0.0f, 0.0f, 1.0f}, n).paired);
  EXPECT_FALSE(s.term(c, {0.0f, 0.0f, 1.0f}, {0.0f, 0.0f, 0.0f}).paired) << "no frame normal";
  EXPECT_FALSE(s.term(c, {0.0f, 0.0f, -1.0f}, n).paired) << "behind the model camera";
  EXPECT_FALSE(s.term(c, {2.0f, 0.0f, 1.0f}, n).paired) << "outside the model image";
  EXPECT_FALSE(s.term(c, {0.0f, 0.0f, 1.06f}, n).paired) << "farther than 5 cm";
  EXPECT_TRUE(s.term(c, {0.0f, 0.0f, 1.04f}, n).paired);
  const float tilt = 31.0f * 3.14159265f / 180.0f;
  EXPECT_FALSE(s.term(c, {0.0f, 0.0f, 1.0f}, {std::sin(tilt), 0.0f, -std::cos(tilt)}).paired)
      << "normals 31 degrees apart";
  const float slight = 29.0f * 3.14159265f / 180.0f;
  EXPECT_TRUE(s.term(c, {0.0f, 0.0f, 1.0f}, {std::sin(slight), 0.0f, -std::cos(slight)}).paired);
  // The model pixel the point projects to has no surface.
  const int32_t centre = 11 * s.camera.width + 15;
  s.normals[static_cast<std::size_t>(centre)] = {0.0f, 0.0f, 0.0f};
  const Vec3f at_centre = s.camera.unproject(15.0f, 11.0f, 1.0f);
  int32_t index = -1;
  EXPECT_TRUE(kernels::icp_model_pixel(c, at_centre, &index));
  EXPECT_EQ(index, centre);
  EXPECT_FALSE(s.term(c, at_centre, n).paired) << "no model surface";
}

TEST(IcpTerm, NearestModelPixelRoundsHalfUp) {
  const Scene s;
  const IcpPass c = s.pass(translation({0.0f, 0.0f, 0.0f}));
  int32_t index = -1;
  // Column 4.49 -> 4, 4.51 -> 5; the image's last half pixel still lands in it, beyond does not.
  EXPECT_TRUE(kernels::icp_model_pixel(c, s.camera.unproject(4.49f, 3.0f, 1.0f), &index));
  EXPECT_EQ(index, 3 * s.camera.width + 4);
  EXPECT_TRUE(kernels::icp_model_pixel(c, s.camera.unproject(4.51f, 3.0f, 1.0f), &index));
  EXPECT_EQ(index, 3 * s.camera.width + 5);
  EXPECT_TRUE(kernels::icp_model_pixel(c, s.camera.unproject(31.4f, 23.4f, 1.0f), &index));
  EXPECT_EQ(index, 23 * s.camera.width + 31);
  EXPECT_FALSE(kernels::icp_model_pixel(c, s.camera.unproject(31.6f, 3.0f, 1.0f), &index));
  EXPECT_FALSE(kernels::icp_model_pixel(c, s.camera.unproject(-0.6f, 3.0f, 1.0f), &index));
  EXPECT_EQ(index, 0) << "a point outside reads pixel 0";
}

}  // namespace
}  // namespace hivox

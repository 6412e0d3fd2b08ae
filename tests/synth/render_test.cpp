#include "hivox/synth/render.h"

#include <gtest/gtest.h>

#include <cmath>

#include "hivox/core/error.h"
#include "hivox/synth/synthetic_dataset.h"
#include "synth/render_test_util.h"

namespace hivox {
namespace {

using Vec3 = Eigen::Vector3d;
using test::oblique_pose;
using test::pixel_ray_c;
using test::small_camera;

TEST(Render, PlaneDepthIsAnalytic) {
  for (const PinholeCamera cam :
       {small_camera(), PinholeCamera{140.f, -135.f, 81.f, 58.f, 160, 120}}) {  // negative fy too
    const Vec3 p0(0, 0, 2.0), n = Vec3(0.1, -0.2, -1.0).normalized();
    SyntheticScene scene;
    scene.add(Plane{p0, n});
    const Pose T = oblique_pose();
    const RenderedFrame f = render(scene, cam, T);
    int valid = 0;
    for (int v = 0; v < cam.height; ++v)
      for (int u = 0; u < cam.width; ++u) {
        // Plane in camera coordinates: n_c . x = n_c . p0_c; the pixel ray is z * r.
        const Vec3 n_c = T.linear().transpose() * n;
        const Vec3 p0_c = T.inverse() * p0;
        const double z = n_c.dot(p0_c) / n_c.dot(pixel_ray_c(cam, u, v));
        ASSERT_GT(z, 0.5);
        ASSERT_NEAR(f.depth_m(u, v), z, 1e-4) << u << "," << v;
        ASSERT_NEAR(f.depth_m(u, v), z, 2e-7 * z);  // exact up to float storage
        const Vec3f nw = f.normal_w(u, v);
        ASSERT_NEAR(nw.x, n.x(), 1e-6);
        ASSERT_NEAR(nw.y, n.y(), 1e-6);
        ASSERT_NEAR(nw.z, n.z(), 1e-6);
        ++valid;
      }
    EXPECT_EQ(valid, cam.width * cam.height);
  }
}

TEST(Render, SphereDepthIsAnalytic) {
  const PinholeCamera cam = small_camera();
  const Vec3 c_w(0.3, -0.1, 1.8);
  const double r = 0.35;
  SyntheticScene scene;
  scene.add(Sphere{c_w, r});
  const Pose T = oblique_pose();
  const RenderedFrame f = render(scene, cam, T);
  const Vec3 c_c = T.inverse() * c_w;
  int hits = 0;
  for (int v = 0; v < cam.height; ++v)
    for (int u = 0; u < cam.width; ++u) {
      // |z ray - c|^2 = r^2: a z^2 - 2 b z + (|c|^2 - r^2) = 0, nearest root.
      const Vec3 ray = pixel_ray_c(cam, u, v);
      const double a = ray.squaredNorm(), b = ray.dot(c_c), cc = c_c.squaredNorm() - r * r;
      const double disc = b * b - a * cc;
      if (std::abs(disc) < 1e-9) continue;  // silhouette: leave tangent rays alone
      if (disc < 0) {
        ASSERT_EQ(f.depth_m(u, v), 0.0f) << u << "," << v;
        continue;
      }
      const double z = (b - std::sqrt(disc)) / a;
      ASSERT_NEAR(f.depth_m(u, v), z, 1e-4) << u << "," << v;
      // Normal: from the centre to the surface point.
      const Vec3 n_w = T.linear() * ((z * ray - c_c) / r);
      const Vec3f nw = f.normal_w(u, v);
      ASSERT_NEAR(nw.x, n_w.x(), 1e-5);
      ASSERT_NEAR(nw.y, n_w.y(), 1e-5);
      ASSERT_NEAR(nw.z, n_w.z(), 1e-5);
      ++hits;
    }
  EXPECT_GT(hits, 1000);
  EXPECT_LT(hits, cam.width * cam.height);
}

TEST(Render, ColourIsShadedAlbedoAndBackgroundElsewhere) {
  SyntheticScene scene;
  Material m;
  m.albedo = {0.8f, 0.4f, 0.2f};
  scene.add(Sphere{Vec3(0, 0, 2), 0.5}, m);
  Lighting light;
  light.to_light_w = Vec3(0, 0, -1);  // towards the camera: the sphere's nearest point is lit
  light.ambient = 0.25f;
  light.background = {1, 2, 3};
  scene.set_lighting(light);
  const PinholeCamera cam = small_camera();
  const RenderedFrame f = render(scene, cam, Pose::Identity());
  // Pixel nearest the optical axis: normal ~ -z, fully lit.
  const Rgb8 centre = f.color(80, 60);
  EXPECT_NEAR(centre.r, 0.8 * 255, 1.5);
  EXPECT_NEAR(centre.g, 0.4 * 255, 1.5);
  EXPECT_NEAR(centre.b, 0.2 * 255, 1.5);
  EXPECT_EQ(f.color(0, 0), (Rgb8{1, 2, 3}));
  EXPECT_EQ(f.depth_m(0, 0), 0.0f);
  EXPECT_EQ(f.normal_w(0, 0).x, 0.0f);
}

TEST(Render, MaxDepthInvalidatesFarPixels) {
  SyntheticScene scene;
  scene.add(Plane{Vec3(0, 0, 3), Vec3(0, 0, -1)});
  const PinholeCamera cam = small_camera();
  EXPECT_NEAR(render(scene, cam, Pose::Identity(), 5.0).depth_m(40, 40), 3.0f, 1e-6);
  const RenderedFrame f = render(scene, cam, Pose::Identity(), 2.5);
  for (std::size_t i = 0; i < f.depth_m.size(); ++i) ASSERT_EQ(f.depth_m.data()[i], 0.0f);
  EXPECT_THROW(render(scene, cam, Pose::Identity(), 0.0), Error);
  EXPECT_THROW(render(scene, PinholeCamera{}, Pose::Identity()), Error);
}

double valid_fraction(const DepthImage& d) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < d.size(); ++i) n += d.data()[i] > 0.0f;
  return static_cast<double>(n) / static_cast<double>(d.size());
}

// Every named scene renders, along its own path, with a plausible share of valid pixels:
// nearly all for the indoor scenes, a clear object in the middle for the single objects.
TEST(Render, EveryNamedSceneLooksAtItsContent) {
  for (const std::string& name : scene_names()) {
    SyntheticParams p;
    p.scene = name;
    p.frames = 6;
    p.width = 160;
    p.height = 120;
    p.noise = NoiseParams::none();
    SyntheticDataset data(p);
    const bool indoor = name == "room" || name == "desk";
    for (std::size_t i = 0; i < data.size(); ++i) {
      const RenderedFrame f = data.render_clean(i);
      const double valid = valid_fraction(f.depth_m);
      if (indoor) {
        EXPECT_GT(valid, 0.99) << name << " frame " << i;
      } else {
        // (The keyboard seen edge-on from low elevations covers ~4% of the image.)
        EXPECT_GT(valid, 0.03) << name << " frame " << i;
        EXPECT_LT(valid, 0.6) << name << " frame " << i;
        // The image centre sees the object.
        int centre_hits = 0;
        for (int v = 50; v < 70; ++v)
          for (int u = 70; u < 90; ++u) centre_hits += f.depth_m(u, v) > 0.0f;
        EXPECT_GT(centre_hits, 100) << name << " frame " << i;
      }
      // Colour is not flat: textures and shading show up.
      int distinct = 0;
      Rgb8 first = f.color(0, 0);
      for (std::size_t k = 0; k < f.color.size(); ++k) distinct += !(f.color.data()[k] == first);
      EXPECT_GT(distinct, 100) << name;
    }
  }
}

}  // namespace
}  // namespace hivox

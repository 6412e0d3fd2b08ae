#include "hivox/synth_mesh/mesh_render.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <utility>

#include "hivox/core/error.h"
#include "hivox/synth/render.h"
#include "hivox/synth/scene.h"
#include "synth/mesh_shapes.h"
#include "synth_mesh/mesh_render_modes.h"
#include "test_util.h"

namespace hivox {
namespace {

using Vec3 = Eigen::Vector3d;
using test::oblique_pose;
using test::pixel_ray_c;
using test::small_camera;

// Barycentric coordinates of the point where the ray o + t d meets the plane of (a, b, c).
Vec3 barycentric(const Vec3& o, const Vec3& d, const Vec3& a, const Vec3& b, const Vec3& c,
                 double* t) {
  // Solve o + t d = a + s (b - a) + r (c - a) for (t, s, r).
  Eigen::Matrix3d M;
  M.col(0) = -d;
  M.col(1) = b - a;
  M.col(2) = c - a;
  const Vec3 x = M.colPivHouseholderQr().solve(o - a);
  *t = x[0];
  return {1.0 - x[1] - x[2], x[1], x[2]};
}

// A tilted triangle with red, green and blue corners, seen from an oblique camera: depth is the
// ray-plane intersection, pixels outside the triangle are empty, the normal faces the camera
// and the colour is the barycentric mix of the corners.
TEST(MeshRender, TriangleDepthNormalAndColourAreAnalytic) {
  const Vec3 a(-0.6, -0.5, 2.0), b(0.7, -0.3, 2.6), c(0.0, 0.6, 1.7);
  TriangleMesh mesh;
  mesh.positions_w = {test::vec3f(a), test::vec3f(b), test::vec3f(c)};
  mesh.colors = {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}};
  mesh.triangles = {{0, 1, 2}};
  // The float vertices are what the renderer sees.
  const Vec3 fa = Vec3(mesh.positions_w[0].x, mesh.positions_w[0].y, mesh.positions_w[0].z);
  const Vec3 fb = Vec3(mesh.positions_w[1].x, mesh.positions_w[1].y, mesh.positions_w[1].z);
  const Vec3 fc = Vec3(mesh.positions_w[2].x, mesh.positions_w[2].y, mesh.positions_w[2].z);
  const MeshScene scene(mesh);
  EXPECT_EQ(scene.triangle_count(), 1);
  EXPECT_TRUE(scene.has_colors());

  const PinholeCamera cam = small_camera();
  const Pose T = oblique_pose();
  const RenderedFrame f = render(scene, cam, T, 10.0);
  ASSERT_EQ(f.depth_m.width(), cam.width);
  ASSERT_EQ(f.depth_m.height(), cam.height);
  EXPECT_TRUE(f.T_wc.isApprox(T));

  Vec3 n = (fb - fa).cross(fc - fa).normalized();
  if (n.dot(fa - T.translation()) > 0) n = -n;  // towards the camera
  int inside = 0, outside = 0;
  for (int v = 0; v < cam.height; ++v)
    for (int u = 0; u < cam.width; ++u) {
      const Vec3 d = T.linear() * pixel_ray_c(cam, u, v);
      double t = 0;
      const Vec3 w = barycentric(T.translation(), d, fa, fb, fc, &t);
      const double margin = w.minCoeff();
      if (margin > 1e-3) {
        ++inside;
        ASSERT_NEAR(f.depth_m(u, v), t, 1e-5) << u << "," << v;
        ASSERT_NEAR(f.depth_m(u, v), t, 2e-7 * t);  // exact up to float storage
        const Vec3f nw = f.normal_w(u, v);
        ASSERT_NEAR(nw.x, n.x(), 1e-6);
        ASSERT_NEAR(nw.y, n.y(), 1e-6);
        ASSERT_NEAR(nw.z, n.z(), 1e-6);
        const Rgb8 col = f.color(u, v);
        ASSERT_NEAR(col.r, 255 * w[0], 1.0) << u << "," << v;
        ASSERT_NEAR(col.g, 255 * w[1], 1.0);
        ASSERT_NEAR(col.b, 255 * w[2], 1.0);
      } else if (margin < -1e-3) {
        ++outside;
        ASSERT_EQ(f.depth_m(u, v), 0.0f) << u << "," << v;
        const Vec3f nw = f.normal_w(u, v);
        ASSERT_EQ(nw.x == 0 && nw.y == 0 && nw.z == 0, true);
        ASSERT_EQ(f.color(u, v), Lighting{}.background);
      }
    }
  EXPECT_GT(inside, 2000);
  EXPECT_GT(outside, 2000);
}

// The same triangle seen from behind: both sides are hit, the normal turns to the camera.
TEST(MeshRender, BackOfATriangleIsHitWithTheNormalTowardsTheCamera) {
  TriangleMesh mesh;
  mesh.positions_w = {{-1, -1, 2}, {1, -1, 2}, {0, 1, 2}};
  mesh.triangles = {{0, 2, 1}};  // normal +z: away from a camera at the origin looking along +z
  const MeshScene scene(mesh);
  const PinholeCamera cam = small_camera();
  const RenderedFrame f = render(scene, cam, Pose::Identity());
  const int u = 80, v = 60;
  EXPECT_NEAR(f.depth_m(u, v), 2.0, 1e-6);
  EXPECT_FLOAT_EQ(f.normal_w(u, v).z, -1.0f);
  // Grey shading of the camera-facing normal, as the analytic renderer shades a surface.
  const Lighting light;
  const float shade = light.ambient + (1.0f - light.ambient) *
                                          static_cast<float>(std::max(0.0, -light.to_light_w.z()));
  const auto grey = static_cast<uint8_t>(std::lround(0.7f * shade * 255.0f));
  EXPECT_EQ(f.color(u, v), (Rgb8{grey, grey, grey}));
}

// A rotated cube from an oblique viewpoint: every pixel against the exact slab intersection of
// the ray with the cube (in the cube's frame). No cracks along the triangles' diagonals.
TEST(MeshRender, CubeDepthAndNormalsAreAnalytic) {
  const Vec3 center(0.2, -0.1, 2.5), half(0.5, 0.4, 0.3);
  const Eigen::Matrix3d R =
      (Eigen::AngleAxisd(0.5, Vec3::UnitZ()) * Eigen::AngleAxisd(0.3, Vec3::UnitX()))
          .toRotationMatrix();
  const MeshScene scene(test::box_mesh(center, half, R));
  EXPECT_EQ(scene.triangle_count(), 12);
  EXPECT_FALSE(scene.has_colors());

  const PinholeCamera cam = small_camera();
  const Pose T = look_at(Vec3(1.2, -1.4, 0.8), center, Vec3::UnitZ());
  const RenderedFrame f = render(scene, cam, T, 10.0);
  int hits = 0, misses = 0, edge = 0;
  for (int v = 0; v < cam.height; ++v)
    for (int u = 0; u < cam.width; ++u) {
      // The ray in the box's frame (the box's float corners differ from the exact ones by
      // ~1e-7 m; the margin below keeps away from its edges).
      const Vec3 o_b = R.transpose() * (T.translation() - center);
      const Vec3 d_b = R.transpose() * (T.linear() * pixel_ray_c(cam, u, v));
      const auto grown = test::ray_box(o_b, d_b, -half.array() - 1e-4, half.array() + 1e-4);
      const auto shrunk = test::ray_box(o_b, d_b, -half.array() + 1e-4, half.array() - 1e-4);
      const auto exact = test::ray_box(o_b, d_b, -half, half);
      if (shrunk) {
        ASSERT_TRUE(exact);
        ++hits;
        ASSERT_NEAR(f.depth_m(u, v), exact->t, 1e-5) << u << "," << v;
        Vec3 n_b = Vec3::Zero();
        n_b[exact->axis] = exact->sign;
        const Vec3 n_w = R * n_b;
        const Vec3f nw = f.normal_w(u, v);
        ASSERT_NEAR(nw.x, n_w.x(), 1e-5) << u << "," << v;
        ASSERT_NEAR(nw.y, n_w.y(), 1e-5);
        ASSERT_NEAR(nw.z, n_w.z(), 1e-5);
      } else if (!grown) {
        ++misses;
        ASSERT_EQ(f.depth_m(u, v), 0.0f) << u << "," << v;
      } else {
        ++edge;
      }
    }
  EXPECT_GT(hits, 3000);
  EXPECT_GT(misses, 3000);
  EXPECT_LT(edge, 200);
}

// Depth beyond max_depth_m is empty, as in the analytic renderer (z distance, not ray length).
TEST(MeshRender, MaxDepthCutsByZ) {
  TriangleMesh mesh;
  mesh.positions_w = {{-10, -10, 3}, {10, -10, 3}, {0, 10, 3}};
  mesh.triangles = {{0, 1, 2}};
  const MeshScene scene(mesh);
  const PinholeCamera cam = small_camera();
  const RenderedFrame near = render(scene, cam, Pose::Identity(), 3.001);
  const RenderedFrame far = render(scene, cam, Pose::Identity(), 2.999);
  // Every pixel of the plane z = 3 has z exactly 3, also at the image corners.
  EXPECT_NEAR(near.depth_m(0, 0), 3.0, 1e-6);
  EXPECT_NEAR(near.depth_m(159, 119), 3.0, 1e-6);
  EXPECT_EQ(far.depth_m(80, 60), 0.0f);
  EXPECT_EQ(far.depth_m(0, 0), 0.0f);
}

TEST(MeshRender, BadMeshesAreClearErrors) {
  TriangleMesh empty;
  Error e = test::error_of([&] { MeshScene s(empty); });
  EXPECT_EQ(e.code(), ErrorCode::InvalidArgument);
  EXPECT_TRUE(test::contains(e.what(), "no triangles")) << e.what();

  TriangleMesh points;
  points.positions_w = {{0, 0, 1}, {1, 0, 1}, {0, 1, 1}};
  e = test::error_of([&] { MeshScene s(points); });
  EXPECT_TRUE(test::contains(e.what(), "no triangles (3 vertices)")) << e.what();

  TriangleMesh nan = points;
  nan.triangles = {{0, 1, 2}};
  nan.positions_w[1].y = std::numeric_limits<float>::quiet_NaN();
  e = test::error_of([&] { MeshScene s(nan); });
  EXPECT_TRUE(test::contains(e.what(), "vertex 1")) << e.what();

  TriangleMesh out_of_range = points;
  out_of_range.triangles = {{0, 1, 3}};
  e = test::error_of([&] { MeshScene s(out_of_range); });
  EXPECT_EQ(e.code(), ErrorCode::InvalidArgument);
}

TEST(MeshRender, MovedSceneRendersTheSameAndTheMovedFromOneSaysSo) {
  MeshScene a(test::box_mesh(Vec3(0, 0, 2), Vec3(0.3, 0.3, 0.3)));
  const PinholeCamera cam = small_camera();
  const RenderedFrame before = render(a, cam, Pose::Identity());
  MeshScene b(std::move(a));
  const RenderedFrame after = render(b, cam, Pose::Identity());
  for (std::size_t k = 0; k < before.depth_m.size(); ++k)
    ASSERT_EQ(before.depth_m.data()[k], after.depth_m.data()[k]);
  const Error e = test::error_of([&] { render(a, cam, Pose::Identity()); });  // NOLINT
  EXPECT_TRUE(test::contains(e.what(), "moved from")) << e.what();
  EXPECT_EQ(a.triangle_count(), 0);  // NOLINT(bugprone-use-after-move)

  MeshScene c(test::box_mesh(Vec3(0, 0, 5), Vec3(1, 1, 1)));
  c = std::move(b);
  EXPECT_EQ(c.triangle_count(), 12);
  EXPECT_NEAR(render(c, cam, Pose::Identity()).depth_m(80, 60), 1.7, 1e-6);

  const Error bad = test::error_of([&] { render(c, cam, Pose::Identity(), 0.0); });
  EXPECT_TRUE(test::contains(bad.what(), "max_depth_m")) << bad.what();
}

// A rotated box on a floor, once as an analytic scene and once as a mesh: the two renderers
// give the same depth, normals and colour (the mesh's float corners move surfaces by ~1e-7 m).
TEST(MeshRender, AgreesWithTheAnalyticRenderer) {
  const Vec3 center(0.1, 0.05, 0.25), half(0.3, 0.2, 0.25);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.4, Vec3::UnitZ()).toRotationMatrix();
  SyntheticScene analytic;
  analytic.add(Plane{Vec3::Zero(), Vec3::UnitZ()});
  analytic.add(Box{center, half, R, 0.0});

  TriangleMesh mesh = test::box_mesh(center, half, R);
  const int32_t k = static_cast<int32_t>(mesh.positions_w.size());
  mesh.positions_w.insert(mesh.positions_w.end(),
                          {{-50, -50, 0}, {50, -50, 0}, {50, 50, 0}, {-50, 50, 0}});
  mesh.triangles.push_back({k, k + 1, k + 2});
  mesh.triangles.push_back({k, k + 2, k + 3});
  const MeshScene scene(mesh);

  const PinholeCamera cam = small_camera();
  for (const Pose& T : {look_at(Vec3(1.5, -1.2, 1.3), Vec3(0, 0, 0.2), Vec3::UnitZ()),
                        look_at(Vec3(-0.9, 1.6, 0.5), Vec3(0.2, 0, 0.3), Vec3::UnitZ())}) {
    const RenderedFrame want = render(analytic, cam, T, 6.0);
    const RenderedFrame got = render(scene, cam, T, 6.0);
    int both = 0, differ = 0;
    double max_diff_m = 0;
    for (int v = 0; v < cam.height; ++v)
      for (int u = 0; u < cam.width; ++u) {
        const float a = want.depth_m(u, v), b = got.depth_m(u, v);
        if (a > 0 && b > 0 && std::abs(a - b) < 1e-4) {
          ++both;
          max_diff_m = std::max(max_diff_m, static_cast<double>(std::abs(a - b)));
          const Vec3f na = want.normal_w(u, v), nb = got.normal_w(u, v);
          ASSERT_NEAR(na.x, nb.x, 1e-5) << u << "," << v;
          ASSERT_NEAR(na.y, nb.y, 1e-5);
          ASSERT_NEAR(na.z, nb.z, 1e-5);
          const Rgb8 ca = want.color(u, v), cb = got.color(u, v);
          ASSERT_LE(std::abs(ca.r - cb.r), 1) << u << "," << v;
          ASSERT_LE(std::abs(ca.g - cb.g), 1);
          ASSERT_LE(std::abs(ca.b - cb.b), 1);
        } else if (a != b) {
          ++differ;  // a silhouette pixel: one ray grazes an edge the other misses
        }
      }
    EXPECT_GT(both, cam.width * cam.height / 2);
    EXPECT_LT(max_diff_m, 2e-6);
    EXPECT_LE(differ, 4);
  }
}

// A bumpy coloured terrain of 2 x 60 x 60 triangles: 4 x 4 ray packets (render) give the same
// frame as one ray per pixel, also in the partial tiles of an image whose sides are not
// multiples of 4.
TEST(MeshRender, PacketsEqualRayByRay) {
  TriangleMesh mesh;
  constexpr int kN = 61;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> height(-0.05f, 0.05f);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int j = 0; j < kN; ++j)
    for (int i = 0; i < kN; ++i) {
      mesh.positions_w.push_back({-1.5f + 3.0f * i / (kN - 1), -1.5f + 3.0f * j / (kN - 1),
                                  height(rng) + 0.2f * std::sin(0.3f * i)});
      mesh.colors.push_back({static_cast<uint8_t>(byte(rng)), static_cast<uint8_t>(byte(rng)),
                             static_cast<uint8_t>(byte(rng))});
    }
  for (int j = 0; j + 1 < kN; ++j)
    for (int i = 0; i + 1 < kN; ++i) {
      const int32_t a = j * kN + i, b = a + 1, c = a + kN, d = c + 1;
      mesh.triangles.push_back({a, b, d});
      mesh.triangles.push_back({a, d, c});
    }
  const MeshScene scene(mesh);
  const PinholeCamera cam{120.f, 118.f, 77.3f, 58.6f, 158, 117};
  const Pose T = look_at(Vec3(0.4, -2.2, 1.6), Vec3(0.1, 0.2, 0), Vec3::UnitZ());
  const RenderedFrame packets = render(scene, cam, T, 4.0);
  const RenderedFrame single = render_mesh(scene, cam, T, 4.0, MeshRayMode::Single);
  int valid = 0;
  for (int v = 0; v < cam.height; ++v)
    for (int u = 0; u < cam.width; ++u) {
      ASSERT_EQ(packets.depth_m(u, v), single.depth_m(u, v)) << u << "," << v;
      ASSERT_EQ(packets.normal_w(u, v), single.normal_w(u, v)) << u << "," << v;
      ASSERT_EQ(packets.color(u, v), single.color(u, v)) << u << "," << v;
      valid += packets.depth_m(u, v) > 0;
    }
  EXPECT_GT(valid, cam.width * cam.height / 2);
  EXPECT_LT(valid, cam.width * cam.height);  // the far end lies beyond 4 m
}

}  // namespace
}  // namespace hivox

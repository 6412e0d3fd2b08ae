#include "hivox/synth/scene.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>

#include "hivox/core/error.h"
#include "test_util.h"

namespace hivox {
namespace {

using Vec3 = Eigen::Vector3d;

Eigen::Matrix3d rot_z(double a) {
  return Eigen::AngleAxisd(a, Vec3::UnitZ()).toRotationMatrix();
}

// Hand-computed signed distances, including signs inside the solids.
TEST(SceneSdf, Plane) {
  const Shape s = Plane{Vec3(0, 0, 1), Vec3(0, 0, 1)};
  EXPECT_DOUBLE_EQ(sdf(s, Vec3(5, -3, 3.5)), 2.5);
  EXPECT_DOUBLE_EQ(sdf(s, Vec3(0, 0, 0.25)), -0.75);
  EXPECT_DOUBLE_EQ(sdf(s, Vec3(1, 1, 1)), 0.0);
}

TEST(SceneSdf, SharpBox) {
  const Shape s = Box{Vec3(1, 2, 3), Vec3(0.1, 0.2, 0.3)};
  EXPECT_NEAR(sdf(s, Vec3(1.3, 2, 3)), 0.2, 1e-12);                  // in front of the +x face
  EXPECT_NEAR(sdf(s, Vec3(1, 2, 2.0)), 0.7, 1e-12);                  // below the -z face
  EXPECT_NEAR(sdf(s, Vec3(1.2, 2.3, 3.4)), std::sqrt(0.03), 1e-12);  // off a corner
  EXPECT_NEAR(sdf(s, Vec3(1, 2, 3)), -0.1, 1e-12);                   // centre: nearest face is +-x
  EXPECT_NEAR(sdf(s, Vec3(1.05, 2, 3)), -0.05, 1e-12);
  EXPECT_NEAR(sdf(s, Vec3(1, 2.15, 3.28)), -0.02, 1e-12);  // nearest face is +z
}

TEST(SceneSdf, RotatedBox) {
  // 90 degrees about z: the box's x half extent (0.1) now lies along world y.
  const Shape s = Box{Vec3::Zero(), Vec3(0.1, 0.4, 0.3), rot_z(M_PI / 2)};
  EXPECT_NEAR(sdf(s, Vec3(0.5, 0, 0)), 0.1, 1e-12);
  EXPECT_NEAR(sdf(s, Vec3(0, 0.5, 0)), 0.4, 1e-12);
  // 45 degrees: a 0.1 cube's corner points along world x at distance 0.1 * sqrt(2).
  const Shape d = Box{Vec3::Zero(), Vec3(0.1, 0.1, 0.1), rot_z(M_PI / 4)};
  EXPECT_NEAR(sdf(d, Vec3(0.5, 0, 0)), 0.5 - 0.1 * std::sqrt(2.0), 1e-12);
}

TEST(SceneSdf, RoundedBox) {
  const Shape s = Box{Vec3::Zero(), Vec3(0.1, 0.1, 0.1), Eigen::Matrix3d::Identity(), 0.02};
  EXPECT_NEAR(sdf(s, Vec3(0.2, 0, 0)), 0.1, 1e-12);  // faces stay where they were
  // Along the diagonal the surface is the corner sphere (centre 0.08 (1,1,1), radius 0.02).
  EXPECT_NEAR(sdf(s, Vec3(0.2, 0.2, 0.2)), std::sqrt(3.0) * 0.12 - 0.02, 1e-12);
  // Beside an edge: the edge cylinder along z through (0.08, 0.08).
  EXPECT_NEAR(sdf(s, Vec3(0.11, 0.11, 0.0)), std::sqrt(2.0) * 0.03 - 0.02, 1e-12);
  EXPECT_NEAR(sdf(s, Vec3::Zero()), -0.1, 1e-12);
}

TEST(SceneSdf, Sphere) {
  const Shape s = Sphere{Vec3(1, 1, 1), 0.2};
  EXPECT_NEAR(sdf(s, Vec3(1.3, 1.4, 1)), 0.3, 1e-12);
  EXPECT_NEAR(sdf(s, Vec3(1, 1, 1)), -0.2, 1e-12);
  EXPECT_NEAR(sdf(s, Vec3(1, 1.15, 1)), -0.05, 1e-12);
}

TEST(SceneSdf, Cylinder) {
  const Shape s = Cylinder{Vec3::Zero(), Vec3::UnitZ(), 0.1, 0.2};
  EXPECT_NEAR(sdf(s, Vec3(0.3, 0, 0)), 0.2, 1e-12);                     // beside the side
  EXPECT_NEAR(sdf(s, Vec3(0.05, 0, 0.5)), 0.3, 1e-12);                  // above the cap
  EXPECT_NEAR(sdf(s, Vec3(0.2, 0, 0.3)), std::hypot(0.1, 0.1), 1e-12);  // off the rim
  EXPECT_NEAR(sdf(s, Vec3(0.05, 0, 0)), -0.05, 1e-12);
  EXPECT_NEAR(sdf(s, Vec3(0, 0, 0.17)), -0.03, 1e-12);
  // Lying along x.
  const Shape x = Cylinder{Vec3(1, 0, 0), Vec3::UnitX(), 0.1, 0.2};
  EXPECT_NEAR(sdf(x, Vec3(1, 0, 0.3)), 0.2, 1e-12);
  EXPECT_NEAR(sdf(x, Vec3(1.5, 0, 0)), 0.3, 1e-12);
}

TEST(SceneSdf, RoomIsFreeInside) {
  const Shape s = Room{Vec3(-2, -2, 0), Vec3(2, 2, 2.5)};
  EXPECT_NEAR(sdf(s, Vec3(0, 0, 1)), 1.0, 1e-12);              // nearest: the floor
  EXPECT_NEAR(sdf(s, Vec3(1.5, 0, 1.2)), 0.5, 1e-12);          // nearest: the +x wall
  EXPECT_NEAR(sdf(s, Vec3(3, 0, 1)), -1.0, 1e-12);             // inside the wall solid
  EXPECT_NEAR(normal(s, Vec3(1.5, 0, 1.2)).x(), -1.0, 1e-12);  // normals point into the room
}

TEST(SceneNormal, KnownNormals) {
  EXPECT_TRUE(normal(Shape{Sphere{Vec3(1, 0, 0), 0.5}}, Vec3(1, 2, 0)).isApprox(Vec3::UnitY()));
  const Shape box = Box{Vec3::Zero(), Vec3(0.1, 0.2, 0.3)};
  EXPECT_TRUE(normal(box, Vec3(0, 0, 0.3)).isApprox(Vec3::UnitZ()));
  EXPECT_TRUE(normal(box, Vec3(-0.1, 0.05, 0.0)).isApprox(-Vec3::UnitX()));
  const Shape cyl = Cylinder{Vec3::Zero(), Vec3::UnitZ(), 0.1, 0.2};
  EXPECT_TRUE(normal(cyl, Vec3(0, 0.1, 0.05)).isApprox(Vec3::UnitY()));
  EXPECT_TRUE(normal(cyl, Vec3(0.03, 0, -0.2)).isApprox(-Vec3::UnitZ()));
}

std::vector<Shape> assorted_shapes() {
  const Eigen::Matrix3d R =
      (Eigen::AngleAxisd(0.3, Vec3::UnitZ()) * Eigen::AngleAxisd(0.5, Vec3(1, 1, 0).normalized()))
          .toRotationMatrix();
  return {Plane{Vec3(0, 0, -0.2), Vec3(0.2, 0.1, 1).normalized()},
          Box{Vec3(0.05, 0, 0.1), Vec3(0.2, 0.1, 0.15), R},
          Box{Vec3(0, 0.1, 0), Vec3(0.2, 0.1, 0.15), R, 0.04},
          Sphere{Vec3(0.1, -0.1, 0.05), 0.25},
          Cylinder{Vec3(0, 0, 0.1), Vec3(1, 2, 3).normalized(), 0.12, 0.2},
          Room{Vec3(-1.5, -1.2, -1.0), Vec3(1.4, 1.3, 1.1)}};
}

// The analytic normal is the SDF gradient: compare with central differences in free space.
TEST(SceneNormal, MatchesSdfGradient) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-0.9, 0.9);
  for (const Shape& s : assorted_shapes()) {
    int checked = 0;
    for (int i = 0; i < 2000 && checked < 200; ++i) {
      const Vec3 p(u(rng), u(rng), u(rng));
      if (sdf(s, p) < 0.01) continue;
      const double h = 1e-6;
      Vec3 g;
      for (int k = 0; k < 3; ++k) {
        Vec3 e = Vec3::Zero();
        e[k] = h;
        g[k] = (sdf(s, p + e) - sdf(s, p - e)) / (2 * h);
      }
      const Vec3 n = normal(s, p);
      EXPECT_NEAR(n.norm(), 1.0, 1e-9) << shape_kind(s);
      EXPECT_LT((n - g).norm(), 1e-5) << shape_kind(s) << " at " << p.transpose();
      ++checked;
    }
    EXPECT_GT(checked, 50) << shape_kind(s);
  }
}

// Sphere tracing on the exact SDF reaches the first surface: an independent check of the
// analytic intersections. Returns -1 when the ray leaves [0, t_max] or does not converge.
double sphere_trace(const Shape& s, const Vec3& o, const Vec3& d, double t_max) {
  double t = 0;
  for (int i = 0; i < 20000; ++i) {
    const double dist = sdf(s, o + t * d);
    if (dist < 1e-10) return t;
    t += dist;
    if (t > t_max) return -1;
  }
  return -2;  // did not converge (grazing ray)
}

TEST(SceneIntersect, AgreesWithSphereTracing) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const Shape& s : assorted_shapes()) {
    int hits = 0, misses = 0;
    for (int i = 0; i < 3000; ++i) {
      const Vec3 o(0.9 * u(rng), 0.9 * u(rng), 0.9 * u(rng));
      if (sdf(s, o) < 0.02) continue;  // origins in free space only
      // Aim at points near the shape so that many rays hit edges and corners.
      const Vec3 aim(0.3 * u(rng), 0.3 * u(rng), 0.3 * u(rng));
      const Vec3 d = (aim - o).normalized();
      const double t_max = 5.0;
      const auto t = intersect(s, o, d, t_max);
      const double traced = sphere_trace(s, o, d, t_max);
      if (traced == -2) continue;
      if (traced < 0) {
        EXPECT_FALSE(t) << shape_kind(s) << ": analytic hit at " << *t << ", tracing missed";
        ++misses;
      } else {
        ASSERT_TRUE(t) << shape_kind(s) << ": tracing hit at " << traced;
        EXPECT_NEAR(*t, traced, 1e-7) << shape_kind(s);
        EXPECT_NEAR(sdf(s, o + *t * d), 0.0, 1e-9) << shape_kind(s);
        ++hits;
      }
    }
    EXPECT_GT(hits, 100) << shape_kind(s);
    if (!std::holds_alternative<Room>(s) && !std::holds_alternative<Plane>(s)) {
      EXPECT_GT(misses, 20) << shape_kind(s);
    }
  }
}

TEST(SceneIntersect, RoundedBoxEdgesAndCorners) {
  // Rays straight at an edge and a corner of a rounded cube hit the rounding, not the sharp box.
  const Shape s = Box{Vec3::Zero(), Vec3(0.1, 0.1, 0.1), Eigen::Matrix3d::Identity(), 0.02};
  const Vec3 diag = Vec3(1, 1, 1).normalized();
  auto t = intersect(s, 2.0 * diag, -diag, 10.0);
  ASSERT_TRUE(t);
  EXPECT_NEAR(*t, 2.0 - (std::sqrt(3.0) * 0.08 + 0.02), 1e-12);
  const Vec3 edge = Vec3(1, 1, 0).normalized();
  t = intersect(s, 2.0 * edge + Vec3(0, 0, 0.05), -edge, 10.0);
  ASSERT_TRUE(t);
  EXPECT_NEAR(*t, 2.0 - (std::sqrt(2.0) * 0.08 + 0.02), 1e-12);
  // A ray that would clip the sharp corner misses the rounded one.
  EXPECT_FALSE(intersect(s, Vec3(0.099, 0.099, 2.0) + Vec3(0.002, 0.002, 0), -Vec3::UnitZ(), 10));
}

TEST(SceneIntersect, RespectsTMaxAndDirection) {
  const Shape s = Sphere{Vec3(0, 0, 2), 0.5};
  EXPECT_NEAR(*intersect(s, Vec3::Zero(), Vec3::UnitZ(), 10), 1.5, 1e-12);
  EXPECT_FALSE(intersect(s, Vec3::Zero(), Vec3::UnitZ(), 1.4));
  EXPECT_FALSE(intersect(s, Vec3::Zero(), -Vec3::UnitZ(), 10));
  const Shape room = Room{Vec3(-1, -1, 0), Vec3(1, 1, 2)};
  EXPECT_NEAR(*intersect(room, Vec3(0, 0, 1), Vec3::UnitX(), 10), 1.0, 1e-12);
  EXPECT_NEAR(*intersect(room, Vec3(0, 0, 0.5), -Vec3::UnitZ(), 10), 0.5, 1e-12);
}

TEST(SceneValidate, NamesTheBadField) {
  auto message = [](const Shape& s) -> std::string {
    try {
      validate(s);
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::InvalidArgument);
      return e.what();
    }
    return "";
  };
  EXPECT_TRUE(test::contains(message(Sphere{Vec3::Zero(), -1}), "radius_m"));
  EXPECT_TRUE(test::contains(message(Plane{Vec3::Zero(), Vec3(0, 0, 2)}), "normal_w"));
  EXPECT_TRUE(test::contains(
      message(Box{Vec3::Zero(), Vec3(0.1, 0.1, 0.1), Eigen::Matrix3d::Identity(), 0.2}),
      "corner_radius_m"));
  EXPECT_TRUE(
      test::contains(message(Cylinder{Vec3::Zero(), Vec3::UnitZ(), 0.1, 0}), "half_height_m"));
  EXPECT_TRUE(test::contains(message(Room{Vec3(1, 0, 0), Vec3(0, 1, 1)}), "min_w"));
  SyntheticScene scene;
  EXPECT_THROW(scene.add(Sphere{Vec3::Zero(), 0}), Error);
  EXPECT_TRUE(scene.primitives().empty());
}

TEST(SceneTexture, CheckerAndStripesAlternate) {
  Material m;
  m.albedo = {1, 0, 0};
  m.albedo2 = {0, 0, 1};
  m.texture = Texture::Checker;
  m.texture_period_m = 0.1;
  const Eigen::Vector3f a = m.color_at(Vec3(0.02, 0.02, 0.02));
  const Eigen::Vector3f b = m.color_at(Vec3(0.12, 0.02, 0.02));
  const Eigen::Vector3f c = m.color_at(Vec3(0.12, 0.12, 0.02));
  EXPECT_NE(a, b);
  EXPECT_EQ(a, c);
  m.texture = Texture::Stripes;
  m.stripe_axis_w = Vec3::UnitZ();
  EXPECT_EQ(m.color_at(Vec3(0, 0, 0.02)), m.color_at(Vec3(5, -3, 0.02)));
  EXPECT_NE(m.color_at(Vec3(0, 0, 0.02)), m.color_at(Vec3(0, 0, 0.12)));
}

// The BVH-accelerated queries equal brute force over all primitives.
TEST(SyntheticScene, BvhQueriesEqualBruteForce) {
  const SyntheticScene scene = make_scene("desk");
  const auto& prims = scene.primitives();
  std::mt19937_64 rng(3);
  const Aabb box = scene.content_bounds();
  std::uniform_real_distribution<double> ux(box.min_w.x(), box.max_w.x()),
      uy(box.min_w.y(), box.max_w.y()), uz(box.min_w.z(), box.max_w.z());
  std::uniform_real_distribution<double> near(-0.3, 0.3);
  for (int i = 0; i < 3000; ++i) {
    // Half the points near the table, where the small primitives are.
    const Vec3 p = i % 2 ? Vec3(ux(rng), uy(rng), uz(rng))
                         : Vec3(near(rng), 0.6 + near(rng), 0.8 + 0.3 * near(rng));
    double best = std::numeric_limits<double>::infinity();
    int best_i = -1;
    for (std::size_t k = 0; k < prims.size(); ++k) {
      const double d = sdf(prims[k].shape, p);
      if (d < best) {
        best = d;
        best_i = static_cast<int>(k);
      }
    }
    ASSERT_EQ(scene.sdf(p), best) << p.transpose();
    ASSERT_EQ(scene.closest_primitive(p), best_i);
    if (best <= 0.0) continue;
    const Vec3 d = Vec3(near(rng), near(rng), near(rng) - 0.2).normalized();
    double t_best = std::numeric_limits<double>::infinity();
    for (const auto& prim : prims)
      if (auto t = intersect(prim.shape, p, d, t_best)) t_best = *t;
    const auto hit = scene.intersect(p, d);
    ASSERT_EQ(hit.has_value(), std::isfinite(t_best));
    if (hit) {
      ASSERT_NEAR(hit->t_m, t_best, 1e-12);  // the scene re-normalises the direction
      EXPECT_NEAR(scene.sdf(hit->p_w), 0.0, 1e-9);
      EXPECT_NEAR(hit->n_w.norm(), 1.0, 1e-9);
      EXPECT_LE(hit->n_w.dot(d), 1e-9);  // the normal faces the ray
    }
  }
}

TEST(SyntheticScene, IntersectNormalisesTheDirection) {
  SyntheticScene scene;
  scene.add(Sphere{Vec3(0, 0, 3), 1.0});
  const auto hit = scene.intersect(Vec3::Zero(), Vec3(0, 0, 7));
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->t_m, 2.0, 1e-12);
  EXPECT_TRUE(hit->p_w.isApprox(Vec3(0, 0, 2)));
  EXPECT_TRUE(hit->n_w.isApprox(-Vec3::UnitZ()));
  EXPECT_EQ(hit->primitive, 0);
  EXPECT_FALSE(scene.intersect(Vec3::Zero(), Vec3(0, 0, 1), 1.5));
  EXPECT_FALSE(SyntheticScene().intersect(Vec3::Zero(), Vec3::UnitZ()));
  EXPECT_EQ(SyntheticScene().closest_primitive(Vec3::Zero()), -1);
}

TEST(MakeScene, UnknownNameListsValidNames) {
  try {
    make_scene("kitchen");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::InvalidArgument);
    const std::string m = e.what();
    EXPECT_TRUE(test::contains(m, "kitchen")) << m;
    for (const std::string& name : scene_names()) EXPECT_TRUE(test::contains(m, name)) << m;
  }
  for (const char* name : {"room", "box", "spheres", "keyboard", "blob", "desk"})
    EXPECT_EQ(make_scene(name).name(), name);
}

std::set<std::string> labels_of(const SyntheticScene& s) {
  std::set<std::string> out;
  for (const auto& p : s.primitives()) out.insert(p.label);
  return out;
}

Aabb bounds_of_label(const SyntheticScene& s, const std::string& label) {
  Aabb b;
  for (const auto& p : s.primitives())
    if (p.label == label) b.extend(bounds(p.shape));
  return b;
}

TEST(MakeScene, OfficeHasRealisticSizes) {
  const SyntheticScene desk = make_scene("desk");
  for (const char* label : {"wall", "floor", "table", "keyboard", "blob", "box", "sphere"})
    EXPECT_TRUE(labels_of(desk).count(label)) << label;
  // Table top at 0.75 m.
  EXPECT_NEAR(desk.sdf(Vec3(0.0, 0.3, 0.76)), 0.01, 1e-9);
  EXPECT_NEAR(bounds_of_label(desk, "table").max_w.z(), 0.75, 1e-6);
  // Keyboard ~45 x 15 cm on the table.
  const Aabb kb = bounds_of_label(desk, "keyboard");
  EXPECT_NEAR(kb.size().x(), 0.45, 0.005);
  EXPECT_NEAR(kb.size().y(), 0.15, 0.005);
  EXPECT_NEAR(kb.min_w.z(), 0.75, 1e-6);
  // Blob 15-30 cm across, standing on the table.
  const Aabb blob = bounds_of_label(desk, "blob");
  EXPECT_GT(blob.size().x(), 0.15);
  EXPECT_LT(blob.size().x(), 0.30);
  EXPECT_NEAR(blob.min_w.z(), 0.748, 1e-6);
  // Room content bounds hold every object.
  const Aabb room = desk.content_bounds();
  EXPECT_TRUE(room.contains(kb.center()));
  EXPECT_NEAR(room.min_w.z(), 0.0, 1e-12);
}

TEST(MakeScene, KeyboardHasFineKeys) {
  const SyntheticScene kb = make_scene("keyboard");
  int keys = 0;
  for (const auto& p : kb.primitives()) {
    const auto* box = std::get_if<Box>(&p.shape);
    ASSERT_NE(box, nullptr);
    if (box->half_extents_m.z() > 0.005) continue;  // the base
    ++keys;
    EXPECT_NEAR(2 * box->half_extents_m.y(), 0.015, 1e-9);  // 15 mm caps
  }
  EXPECT_GT(keys, 100);
  // Keys 10 and 11 of row 3 are centred at x = -+9.5 mm, y = 9.5 mm: the middle of the 4 mm gap
  // between them, at mid key height, is 2 mm from both.
  const double key_top = kb.content_bounds().max_w.z();
  EXPECT_NEAR(kb.sdf(Vec3(0.0, 0.0095, key_top - 0.004)), 0.002, 1e-9);
  EXPECT_NEAR(kb.sdf(Vec3(0.0095, 0.0095, key_top + 0.01)), 0.01, 1e-9);  // above a key
}

TEST(MakeScene, SpheresAreDisjointAndBlobBumpsAreSmall) {
  const SyntheticScene s = make_scene("spheres");
  const auto& p = s.primitives();
  for (std::size_t i = 0; i < p.size(); ++i)
    for (std::size_t j = i + 1; j < p.size(); ++j) {
      const auto& a = std::get<Sphere>(p[i].shape);
      const auto& b = std::get<Sphere>(p[j].shape);
      EXPECT_GT((a.center_w - b.center_w).norm(), a.radius_m + b.radius_m + 0.01);
    }
  const SyntheticScene blob = make_scene("blob");
  EXPECT_GT(blob.primitives().size(), 50u);
  for (std::size_t i = 1; i < blob.primitives().size(); ++i) {
    const double r = std::get<Sphere>(blob.primitives()[i].shape).radius_m;
    EXPECT_GE(r, 0.01);
    EXPECT_LE(r, 0.04);
  }
}

}  // namespace
}  // namespace hivox

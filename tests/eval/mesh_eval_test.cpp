// A mesh against a reference mesh, on meshes whose distances are known exactly: the same mesh
// (0, F-score 1), a plane shifted by d (every distance d), half a plane (accuracy 0, half
// recalled), a unit cube against a larger one; the closest point on a triangle against a brute
// force search; sampling by area.

#include "hivox/eval/mesh_eval.h"

#include <gtest/gtest.h>

#include <random>

#include "hivox/core/error.h"
#include "mesh_test_util.h"

namespace hivox {
namespace {

TriangleMesh plane(int w, int h, float cell, float z) {
  return test::plane_mesh(w, h, cell, z);
}

/// An axis-aligned cube of side `s` centred at the origin: 8 corners, 12 triangles.
TriangleMesh cube(float s) {
  TriangleMesh m;
  const float h = s / 2;
  for (int i = 0; i < 8; ++i)
    m.positions_w.push_back({i & 1 ? h : -h, i & 2 ? h : -h, i & 4 ? h : -h});
  const int quads[6][4] = {{0, 1, 3, 2}, {4, 6, 7, 5}, {0, 4, 5, 1},
                           {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 5, 7, 3}};
  for (const auto& q : quads) {
    m.triangles.push_back({q[0], q[1], q[2]});
    m.triangles.push_back({q[0], q[2], q[3]});
  }
  return m;
}

MeshEvalParams mesh_samples(int64_t samples = 20000) {
  MeshEvalParams p;
  p.samples = samples;
  p.thresholds_m = {0.001, 0.005, 0.01};
  return p;
}

TEST(MeshEval, IdenticalMeshesAreZeroApartWithFScoreOne) {
  const TriangleMesh m = plane(40, 30, 0.01f, 0.0f);
  const MeshEvalResult r = evaluate_mesh(m, m, mesh_samples());
  EXPECT_LT(r.accuracy.max_m, 1e-6);
  EXPECT_LT(r.completeness.max_m, 1e-6);
  EXPECT_LT(r.chamfer_m, 1e-6);
  for (const FScore& f : r.fscores) {
    EXPECT_EQ(f.precision, 1.0);
    EXPECT_EQ(f.recall, 1.0);
    EXPECT_EQ(f.fscore, 1.0);
  }
  EXPECT_EQ(r.mesh_samples, 20000);
  // Also with big triangles (a cube of 12): every sample lies on the other's surface.
  const MeshEvalResult c = evaluate_mesh(cube(1.0f), cube(1.0f), mesh_samples());
  EXPECT_LT(c.accuracy.max_m, 1e-6);
}

TEST(MeshEval, AShiftedPlaneIsTheShiftAwayEverywhere) {
  const float d = 0.003f;
  // The shifted plane's samples all project inside the reference: every distance is d.
  const MeshEvalResult r =
      evaluate_mesh(plane(40, 30, 0.01f, d), plane(40, 30, 0.01f, 0.0f), mesh_samples());
  EXPECT_NEAR(r.accuracy.mean_m, d, 1e-6);
  EXPECT_NEAR(r.accuracy.median_m, d, 1e-6);
  EXPECT_NEAR(r.accuracy.max_m, d, 1e-6);
  EXPECT_NEAR(r.completeness.mean_m, d, 1e-6);
  EXPECT_NEAR(r.chamfer_m, d, 1e-6);
  EXPECT_EQ(r.fscores[0].fscore, 0.0);  // 1 mm < 3 mm
  EXPECT_EQ(r.fscores[1].fscore, 1.0);  // 5 mm
  EXPECT_EQ(r.fscores[2].fscore, 1.0);
}

TEST(MeshEval, HalfAPlaneIsAccurateButHalfComplete) {
  const TriangleMesh full = plane(40, 20, 0.01f, 0.0f);  // 0.4 x 0.2 m
  const TriangleMesh half = plane(20, 20, 0.01f, 0.0f);  // x in [0, 0.2]
  const MeshEvalResult r = evaluate_mesh(half, full, mesh_samples(40000));
  EXPECT_LT(r.accuracy.max_m, 1e-6);
  EXPECT_EQ(r.fscores[1].precision, 1.0);
  // The other half of the reference is 0..0.2 m from the mesh (mean 0.1 m), and within 5 mm
  // for a 5 mm strip of it: recall 0.5 + 0.025 / 2.
  EXPECT_NEAR(r.completeness.mean_m, 0.5 * 0.1, 0.003);
  EXPECT_NEAR(r.completeness.max_m, 0.2, 0.002);
  EXPECT_NEAR(r.fscores[1].recall, 0.5 + 0.5 * 0.025, 0.01);
  const double p = 1.0, rc = r.fscores[1].recall;
  EXPECT_NEAR(r.fscores[1].fscore, 2 * p * rc / (p + rc), 1e-12);
}

TEST(MeshEval, AReferenceFilterLimitsCompletenessToWhatItKeeps) {
  const TriangleMesh full = plane(40, 20, 0.01f, 0.0f);  // 0.4 x 0.2 m
  const TriangleMesh half = plane(20, 20, 0.01f, 0.0f);  // x in [0, 0.2]
  MeshEvalParams p = mesh_samples(40000);
  // The part of the reference the "cameras saw": the half the mesh covers.
  p.reference_filter = [](const Vec3f& q) { return q.x <= 0.2f; };
  const MeshEvalResult r = evaluate_mesh(half, full, p);
  EXPECT_NEAR(r.reference_kept, 0.5, 0.01);
  EXPECT_LT(r.completeness.max_m, 1e-6);
  EXPECT_EQ(r.fscores[1].recall, 1.0);
  EXPECT_LT(r.accuracy.max_m, 1e-6);  // unaffected
  p.reference_filter = [](const Vec3f&) { return false; };
  EXPECT_THROW(evaluate_mesh(half, full, p), Error);
}

TEST(MeshEval, CubesOfTwoSizesAreHalfTheirDifferenceApart) {
  // Samples of the inner cube's faces lie 0.1 m inside the outer cube's faces.
  const MeshEvalResult r = evaluate_mesh(cube(1.0f), cube(1.2f), mesh_samples());
  EXPECT_NEAR(r.accuracy.mean_m, 0.1, 1e-5);
  EXPECT_NEAR(r.accuracy.max_m, 0.1, 1e-5);
  // The outer cube's samples: 0.1 m from the inner faces in front of them, more near the edges.
  EXPECT_GE(r.completeness.mean_m, 0.1 - 1e-6);
  EXPECT_LE(r.completeness.max_m, 0.1 * std::sqrt(3.0) + 1e-5);
}

TEST(MeshEval, ClosestPointOnATriangleMatchesABruteForceSearch) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int trial = 0; trial < 200; ++trial) {
    const Vec3f a{u(rng), u(rng), u(rng)}, b{u(rng), u(rng), u(rng)}, c{u(rng), u(rng), u(rng)};
    const Vec3f p{2 * u(rng), 2 * u(rng), 2 * u(rng)};
    const float exact = norm(closest_point_on_triangle(p, a, b, c) - p);
    float brute = INFINITY;
    const int n = 300;
    for (int i = 0; i <= n; ++i)
      for (int j = 0; i + j <= n; ++j) {
        const Vec3f q =
            a + (b - a) * (static_cast<float>(i) / n) + (c - a) * (static_cast<float>(j) / n);
        brute = std::min(brute, norm(q - p));
      }
    EXPECT_LE(exact, brute + 1e-5f) << trial;  // never farther than any point of the triangle
    EXPECT_GE(exact, brute - 0.01f) << trial;  // and the grid comes within its spacing
  }
}

TEST(MeshEval, SurfaceDistanceIsExactAgainstEveryTriangle) {
  // A plane of small triangles plus one big triangle far off: far queries stay exact too.
  TriangleMesh m = plane(20, 20, 0.01f, 0.0f);
  const auto base = static_cast<int32_t>(m.positions_w.size());
  m.positions_w.insert(m.positions_w.end(), {{1, 0, 0.5f}, {3, 0, 0.5f}, {1, 2, 0.7f}});
  m.triangles.push_back({base, base + 1, base + 2});
  const SurfaceDistance surface(m, 10.0);  // exact everywhere here
  const SurfaceDistance near_only(m, 0.05);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1.0f, 3.0f);
  for (int i = 0; i < 300; ++i) {
    const Vec3f p{u(rng), u(rng), u(rng)};
    double brute = INFINITY;
    for (const auto& t : m.triangles)
      brute = std::min<double>(
          brute, norm(closest_point_on_triangle(p, m.positions_w[t[0]], m.positions_w[t[1]],
                                                m.positions_w[t[2]]) -
                      p));
    EXPECT_NEAR(surface.distance(p), brute, 1e-6) << i;
    // Exact near the surface, at most one anchor spacing too long beyond.
    const double d = near_only.distance(p);
    if (brute < 0.05) {
      EXPECT_NEAR(d, brute, 1e-6) << i;
    }
    EXPECT_GE(d, brute - 1e-6) << i;
    EXPECT_LE(d, brute + near_only.spacing_m() + 1e-6) << i;
  }
}

TEST(MeshEval, SamplesAreUniformByArea) {
  // Two triangles of areas 1 and 3 (m^2): a quarter of the samples on the first.
  TriangleMesh m;
  m.positions_w = {{0, 0, 0}, {2, 0, 0}, {0, 1, 0}, {10, 0, 0}, {13, 0, 0}, {10, 2, 0}};
  m.triangles = {{0, 1, 2}, {3, 4, 5}};
  const std::vector<Vec3f> s = sample_surface(m, 40000, 5);
  const auto first = std::count_if(s.begin(), s.end(), [](const Vec3f& p) { return p.x < 5; });
  EXPECT_NEAR(static_cast<double>(first) / 40000.0, 0.25, 0.01);
  for (const Vec3f& p : s) {
    EXPECT_EQ(p.z, 0.0f);
    if (p.x < 5) {
      EXPECT_LE(p.x / 2 + p.y, 1.0f + 1e-5f);  // inside the first triangle
    }
  }
  EXPECT_EQ(sample_surface(m, 100, 9)[42].x, sample_surface(m, 100, 9)[42].x);  // seeded
}

TEST(MeshEval, RefusesMeshesWithoutSurfaceAndBadSettings) {
  TriangleMesh flat;
  flat.positions_w = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}};
  flat.triangles = {{0, 1, 2}};  // collinear: no area
  EXPECT_THROW(evaluate_mesh(flat, cube(1.0f), mesh_samples()), Error);
  EXPECT_THROW(evaluate_mesh(cube(1.0f), TriangleMesh{}, mesh_samples()), Error);
  MeshEvalParams p;
  p.samples = 0;
  EXPECT_THROW(p.validate(), Error);
  p = {};
  p.thresholds_m = {0.005, -1};
  EXPECT_THROW(p.validate(), Error);
}

}  // namespace
}  // namespace hivox

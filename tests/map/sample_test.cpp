#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "map/sample_kernels.h"

namespace hivox {
namespace {

// A function of the interpolant's form with random coefficients.
struct TrilinearForm {
  float a[8];
  float operator()(const Vec3f& p) const {
    return a[0] * p.x * p.y * p.z + a[1] * p.x * p.y + a[2] * p.y * p.z + a[3] * p.x * p.z +
           a[4] * p.x + a[5] * p.y + a[6] * p.z + a[7];
  }
  Vec3f gradient(const Vec3f& p) const {
    return {a[0] * p.y * p.z + a[1] * p.y + a[3] * p.z + a[4],
            a[0] * p.x * p.z + a[1] * p.x + a[2] * p.z + a[5],
            a[0] * p.x * p.y + a[2] * p.y + a[3] * p.x + a[6]};
  }
};

TEST(IrregularInterpolation, ReproducesItsFormExactlyAtIrregularPositions) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> coef(-1.0f, 1.0f), jitter(-0.45f, 0.45f), in(0.0f, 1.0f);
  for (int trial = 0; trial < 200; ++trial) {
    TrilinearForm f;
    for (float& c : f.a) c = coef(rng);
    Vec3f pos[8];
    float val[8];
    const Vec3f offset{coef(rng) * 10, coef(rng) * 10, coef(rng) * 10};  // anywhere in space
    for (int c = 0; c < 8; ++c) {
      // Corners of a cube, each moved by up to 0.45: irregular but not degenerate.
      pos[c] = Vec3f{static_cast<float>(c & 1) + jitter(rng),
                     static_cast<float>((c >> 1) & 1) + jitter(rng),
                     static_cast<float>(c >> 2) + jitter(rng)} +
               offset;
      val[c] = f(pos[c]);
    }
    for (int k = 0; k < 5; ++k) {
      const Vec3f p = Vec3f{in(rng), in(rng), in(rng)} + offset;
      float got;
      Vec3f grad;
      ASSERT_TRUE(kernels::interpolate_irregular(pos, val, p, &got, &grad));
      EXPECT_NEAR(got, f(p), 2e-3f) << "trial " << trial;
      const Vec3f g = f.gradient(p);
      EXPECT_NEAR(grad.x, g.x, 5e-3f);
      EXPECT_NEAR(grad.y, g.y, 5e-3f);
      EXPECT_NEAR(grad.z, g.z, 5e-3f);
    }
  }
}

TEST(IrregularInterpolation, ReducesToTrilinearOnARegularCube) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> v(-1.0f, 1.0f), in(0.0f, 1.0f);
  for (int trial = 0; trial < 100; ++trial) {
    Vec3f pos[8];
    float val[8];
    for (int c = 0; c < 8; ++c) {
      pos[c] = {static_cast<float>(c & 1) + 5.0f, static_cast<float>((c >> 1) & 1) - 3.0f,
                static_cast<float>(c >> 2) + 7.0f};
      val[c] = v(rng);
    }
    const Vec3f t{in(rng), in(rng), in(rng)};
    Vec3f g_tri, g_irr;
    const float tri = kernels::interpolate_trilinear(val, t, &g_tri);
    float irr;
    ASSERT_TRUE(kernels::interpolate_irregular(pos, val, t + pos[0], &irr, &g_irr));
    EXPECT_NEAR(irr, tri, 1e-5f);
    EXPECT_NEAR(g_irr.x, g_tri.x, 1e-4f);
    EXPECT_NEAR(g_irr.y, g_tri.y, 1e-4f);
    EXPECT_NEAR(g_irr.z, g_tri.z, 1e-4f);
  }
}

TEST(IrregularInterpolation, DegenerateConfigurationsAreRejectedWithoutNaN) {
  Vec3f pos[8];
  float val[8];
  for (int c = 0; c < 8; ++c) {
    pos[c] = {static_cast<float>(c & 1), static_cast<float>((c >> 1) & 1),
              static_cast<float>(c >> 2)};
    val[c] = static_cast<float>(c);
  }
  // Two samples at the same place (two corners took the same coarse voxel).
  Vec3f twice[8];
  std::copy(pos, pos + 8, twice);
  twice[3] = twice[1];
  float f = 12345.0f;
  Vec3f g{7, 7, 7};
  EXPECT_FALSE(kernels::interpolate_irregular(twice, val, {0.5f, 0.5f, 0.5f}, &f, &g));
  EXPECT_EQ(f, 12345.0f) << "outputs untouched: the caller falls back";
  // All samples on a plane.
  Vec3f flat[8];
  for (int c = 0; c < 8; ++c) flat[c] = {pos[c].x, pos[c].y, 0.0f};
  EXPECT_FALSE(kernels::interpolate_irregular(flat, val, {0.5f, 0.5f, 0.5f}, &f, &g));
  // Pivoting matters: sample 1 lies on the x = 0 plane with sample 0, which makes the first
  // pivot candidate zero for a solver without row exchanges; with pivoting it solves.
  Vec3f tricky[8] = {{0, 0, 0}, {0, 1.2f, 0.3f}, {1, 0, 0},    {1, 1, 0},
                     {0, 0, 1}, {1, 0, 1},       {0.1f, 1, 1}, {1, 1, 1}};
  TrilinearForm form{{0.3f, -0.2f, 0.5f, 0.1f, 1.0f, -1.0f, 0.25f, 0.7f}};
  float tv[8];
  for (int c = 0; c < 8; ++c) tv[c] = form(tricky[c]);
  ASSERT_TRUE(kernels::interpolate_irregular(tricky, tv, {0.4f, 0.6f, 0.5f}, &f, &g));
  EXPECT_NEAR(f, form({0.4f, 0.6f, 0.5f}), 1e-4f);
  EXPECT_FALSE(std::isnan(f));
}

}  // namespace
}  // namespace hivox

#include "hivox/core/camera.h"

#include <gtest/gtest.h>

#include "hivox/core/error.h"
#include "test_util.h"

namespace hivox {
namespace {

PinholeCamera tum_like() {
  return {525.0f, 525.0f, 319.5f, 239.5f, 640, 480};
}

TEST(Camera, ProjectUnprojectRoundTrip) {
  for (const PinholeCamera cam :
       {tum_like(), PinholeCamera{481.2f, -480.0f, 319.5f, 239.5f, 640, 480}}) {
    for (float u : {0.0f, 100.25f, 319.5f, 639.0f})
      for (float v : {0.0f, 77.5f, 479.0f})
        for (float z : {0.3f, 1.7f, 6.0f}) {
          const Vec3f p = cam.unproject(u, v, z);
          EXPECT_FLOAT_EQ(p.z, z);
          const Vec2f uv = cam.project(p);
          EXPECT_NEAR(uv.x, u, 1e-3f);
          EXPECT_NEAR(uv.y, v, 1e-3f);
        }
  }
}

TEST(Camera, PrincipalPointIsOnOpticalAxis) {
  const PinholeCamera cam = tum_like();
  const Vec3f p = cam.unproject(cam.cx, cam.cy, 2.0f);
  EXPECT_FLOAT_EQ(p.x, 0.0f);
  EXPECT_FLOAT_EQ(p.y, 0.0f);
}

TEST(Camera, NegativeFyMirrorsVertically) {
  PinholeCamera down = tum_like();
  PinholeCamera up = down;
  up.fy = -down.fy;
  // A point below the optical axis (y > 0 in OpenCV axes) lands below the centre with fy > 0 and
  // above it with fy < 0, at the mirrored row.
  const Vec3f p{0.1f, 0.2f, 1.0f};
  const Vec2f a = down.project(p);
  const Vec2f b = up.project(p);
  EXPECT_GT(a.y, down.cy);
  EXPECT_LT(b.y, up.cy);
  EXPECT_NEAR(a.y - down.cy, up.cy - b.y, 1e-4f);
  EXPECT_FLOAT_EQ(a.x, b.x);
  EXPECT_NO_THROW(up.validate());
}

TEST(Camera, ScaledKeepsRaysThroughPixelCentres) {
  const PinholeCamera cam = tum_like();
  const PinholeCamera half = cam.scaled(0.5f);
  EXPECT_EQ(half.width, 320);
  EXPECT_EQ(half.height, 240);
  // Pixel (0,0) of the half image covers full-resolution pixels 0..1, centred at 0.5.
  const Vec3f r_half = half.ray(0.0f, 0.0f);
  const Vec3f r_full = cam.ray(0.5f, 0.5f);
  EXPECT_NEAR(r_half.x, r_full.x, 1e-6f);
  EXPECT_NEAR(r_half.y, r_full.y, 1e-6f);
}

TEST(Camera, SubsampledRoundsOddSizesDown) {
  PinholeCamera cam = tum_like();
  cam.width = 161;
  cam.height = 121;
  const PinholeCamera quarter = cam.subsampled(4);
  EXPECT_EQ(quarter.width, 40);  // whole 4x4 blocks only
  EXPECT_EQ(quarter.height, 30);
  // Pixel (0,0) of the quarter image covers full-resolution pixels 0..3, centred at 1.5.
  const Vec3f r_quarter = quarter.ray(0.0f, 0.0f);
  const Vec3f r_full = cam.ray(1.5f, 1.5f);
  EXPECT_NEAR(r_quarter.x, r_full.x, 1e-6f);
  EXPECT_NEAR(r_quarter.y, r_full.y, 1e-6f);
}

TEST(Camera, ValidateNamesTheBadField) {
  auto expect_fail = [](PinholeCamera c, const std::string& field) {
    try {
      c.validate("intrinsics.json");
      FAIL() << "expected an error for " << field;
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::InvalidArgument);
      EXPECT_TRUE(test::contains(e.what(), field)) << e.what();
      EXPECT_TRUE(test::contains(e.what(), "intrinsics.json")) << e.what();
    }
  };
  PinholeCamera c = tum_like();
  c.fx = 0;
  expect_fail(c, "fx");
  c = tum_like();
  c.fx = -500;
  expect_fail(c, "fx");
  c = tum_like();
  c.fy = 0;
  expect_fail(c, "fy");
  c = tum_like();
  c.width = 0;
  expect_fail(c, "size");
  c = tum_like();
  c.cx = std::nanf("");
  expect_fail(c, "principal point");
}

}  // namespace
}  // namespace hivox

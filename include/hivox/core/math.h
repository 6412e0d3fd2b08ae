#pragma once
/// @file
/// Small plain-data vector and matrix types for kernels (host and device). The public API uses
/// Eigen; kernels use these so that the same code compiles under nvcc without Eigen.

#include <cmath>
#include <cstdint>
#include <cstring>

#include "hivox/core/hd.h"

namespace hivox {

struct Vec2f {
  float x = 0, y = 0;
};

struct Vec3f {
  float x = 0, y = 0, z = 0;
  HIVOX_HD float& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
  HIVOX_HD float operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
};

struct Vec3i {
  int32_t x = 0, y = 0, z = 0;
  HIVOX_HD int32_t& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
  HIVOX_HD int32_t operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
};

HIVOX_HD inline bool operator==(const Vec3i& a, const Vec3i& b) {
  return a.x == b.x && a.y == b.y && a.z == b.z;
}
HIVOX_HD inline bool operator!=(const Vec3i& a, const Vec3i& b) {
  return !(a == b);
}
HIVOX_HD inline bool operator==(const Vec3f& a, const Vec3f& b) {
  return a.x == b.x && a.y == b.y && a.z == b.z;
}
HIVOX_HD inline Vec3i operator+(const Vec3i& a, const Vec3i& b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z};
}

HIVOX_HD inline Vec3f operator+(const Vec3f& a, const Vec3f& b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z};
}
HIVOX_HD inline Vec3f operator-(const Vec3f& a, const Vec3f& b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
HIVOX_HD inline Vec3f operator-(const Vec3f& a) {
  return {-a.x, -a.y, -a.z};
}
HIVOX_HD inline Vec3f operator*(const Vec3f& a, float s) {
  return {a.x * s, a.y * s, a.z * s};
}
HIVOX_HD inline Vec3f operator*(float s, const Vec3f& a) {
  return a * s;
}
HIVOX_HD inline Vec3f operator/(const Vec3f& a, float s) {
  return a * (1.0f / s);
}
HIVOX_HD inline Vec3f& operator+=(Vec3f& a, const Vec3f& b) {
  a = a + b;
  return a;
}
HIVOX_HD inline float dot(const Vec3f& a, const Vec3f& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
HIVOX_HD inline Vec3f cross(const Vec3f& a, const Vec3f& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
HIVOX_HD inline float norm(const Vec3f& a) {
  return std::sqrt(dot(a, a));
}
HIVOX_HD inline Vec3f normalized(const Vec3f& a) {
  const float n = norm(a);
  return n > 0.0f ? a / n : Vec3f{0, 0, 0};
}
HIVOX_HD inline Vec3f to_float(const Vec3i& a) {
  return {static_cast<float>(a.x), static_cast<float>(a.y), static_cast<float>(a.z)};
}
HIVOX_HD inline Vec3i floor_to_int(const Vec3f& a) {
  return {static_cast<int32_t>(std::floor(a.x)), static_cast<int32_t>(std::floor(a.y)),
          static_cast<int32_t>(std::floor(a.z))};
}

/// Floor division by a positive power-of-two-free divisor that is correct for negatives.
HIVOX_HD inline int32_t floor_div(int32_t a, int32_t b) {
  const int32_t q = a / b;
  return (a % b != 0 && ((a < 0) != (b < 0))) ? q - 1 : q;
}

/// Row-major 3x3 matrix.
struct Mat3f {
  float m[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  HIVOX_HD float operator()(int r, int c) const { return m[r * 3 + c]; }
  HIVOX_HD float& operator()(int r, int c) { return m[r * 3 + c]; }
  HIVOX_HD Vec3f col(int c) const { return {m[c], m[3 + c], m[6 + c]}; }
};

HIVOX_HD inline Vec3f operator*(const Mat3f& a, const Vec3f& v) {
  return {a.m[0] * v.x + a.m[1] * v.y + a.m[2] * v.z, a.m[3] * v.x + a.m[4] * v.y + a.m[5] * v.z,
          a.m[6] * v.x + a.m[7] * v.y + a.m[8] * v.z};
}
HIVOX_HD inline Mat3f transpose(const Mat3f& a) {
  Mat3f t;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) t.m[r * 3 + c] = a.m[c * 3 + r];
  return t;
}

/// Rigid transform `p_a = R * p_b + t` in single precision, for kernels. Named like poses:
/// a `Rigid3f T_cw` maps world points into the camera frame.
struct Rigid3f {
  Mat3f R;
  Vec3f t;
  HIVOX_HD Vec3f operator*(const Vec3f& p) const { return R * p + t; }
  HIVOX_HD Vec3f rotate(const Vec3f& v) const { return R * v; }
  HIVOX_HD Rigid3f inverse() const {
    Rigid3f inv;
    inv.R = transpose(R);
    inv.t = -(inv.R * t);
    return inv;
  }
};

HIVOX_HD inline float clampf(float v, float lo, float hi) {
  return v < lo ? lo : (v > hi ? hi : v);
}

/// `next` when it is beyond `z`, else the float just above `z`: a ray march's step that is lost
/// to rounding (a step far below `z`'s precision, e.g. micrometre voxels metres away) still moves.
HIVOX_HD inline float step_beyond(float z, float next) {
  return next > z ? next : nextafterf(z, INFINITY);
}

/// floor(x) for 0 <= x < 2^23, branch-free and free of library calls so that loops over it
/// vectorize (floorf does not without fast-math): x + 2^23 - 2^23 is x rounded to the nearest
/// integer, one less where that rounded up. Other x give some value without trapping.
HIVOX_HD inline float floor_nonnegative(float x) {
  constexpr float kTwo23 = 8388608.0f;
  const float rounded = (x + kTwo23) - kTwo23;
  return rounded > x ? rounded - 1.0f : rounded;
}

/// e^x for finite x <= 0 to a relative error below 4.2e-6 (0 below -87, where e^x leaves the
/// normal floats), branch-free and free of library calls so that loops over it vectorize
/// (std::exp and floorf do not without fast-math): x log2(e) = n + f with n an integer and
/// |f| <= 1/2, 2^f by its Taylor series to degree 6, 2^n from the exponent bits.
HIVOX_HD inline float exp_nonpositive(float x) {
  const float t = x * 1.44269504f;
  const int32_t n = static_cast<int32_t>(t - 0.5f);  // rounds t <= 0 to an integer
  const float g = (t - static_cast<float>(n)) * 0.693147181f;
  const float p =
      1.0f + g * (1.0f + g * (0.5f + g * (1.0f / 6 +
                                          g * (1.0f / 24 + g * (1.0f / 120 + g * (1.0f / 720))))));
  const int32_t bits = n < -126 ? 0 : (n + 127) << 23;
  float scale;
  memcpy(&scale, &bits, sizeof scale);
  return p * scale;
}

}  // namespace hivox

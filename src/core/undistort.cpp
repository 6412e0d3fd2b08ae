#include "hivox/core/undistort.h"

#include <cmath>

#include "core/parallel.h"
#include "hivox/core/error.h"

namespace hivox {

namespace {
constexpr float kOutside = -2.0f;  // source position of an output pixel with no input
}  // namespace

Undistorter::Undistorter(const PinholeCamera& camera, const LensDistortion& distortion)
    : camera_(camera), distortion_(distortion) {
  camera.validate("camera to undistort");
  distortion.validate("camera to undistort");
  source_.resize(static_cast<std::size_t>(camera.width) * camera.height);
  for (int v = 0; v < camera.height; ++v)
    for (int u = 0; u < camera.width; ++u) {
      const Vec3f ray = camera.ray(static_cast<float>(u), static_cast<float>(v));
      const Vec2f d = distortion.distort({ray.x, ray.y});
      Vec2f src = camera.project({d.x, d.y, 1.0f});
      // Sources within half a pixel of the border still have a nearest pixel inside.
      if (!(src.x >= -0.5f && src.y >= -0.5f && src.x <= static_cast<float>(camera.width) - 0.5f &&
            src.y <= static_cast<float>(camera.height) - 0.5f)) {
        src = {kOutside, kOutside};
        ++outside_;
      }
      source_[static_cast<std::size_t>(v) * camera.width + u] = src;
    }
}

void Undistorter::check_size(int width, int height, const char* what) const {
  if (width != camera_.width || height != camera_.height)
    fail(ErrorCode::InvalidArgument, "undistort: {} image is {}x{} but the camera is {}x{}", what,
         width, height, camera_.width, camera_.height);
}

DepthImage Undistorter::depth(const DepthImage& in) const {
  check_size(in.width(), in.height(), "depth");
  DepthImage out(in.width(), in.height(), 0.0f);
  const int w = in.width(), h = in.height();
  parallel_for(static_cast<int64_t>(source_.size()), [&](int64_t i) {
    const Vec2f s = source_[static_cast<std::size_t>(i)];
    if (s.x == kOutside) return;
    // Nearest pixel: s >= -0.5, so truncating s + 0.5 rounds (a libm call per pixel does not).
    const int x = static_cast<int>(s.x + 0.5f), y = static_cast<int>(s.y + 0.5f);
    out.data()[i] = in(x < w ? x : w - 1, y < h ? y : h - 1);
  });
  return out;
}

ColorImage Undistorter::color(const ColorImage& in) const {
  check_size(in.width(), in.height(), "colour");
  ColorImage out(in.width(), in.height());
  const int w = in.width(), h = in.height();
  parallel_for(static_cast<int64_t>(source_.size()), [&](int64_t i) {
    const Vec2f s = source_[static_cast<std::size_t>(i)];
    if (s.x == kOutside) return;
    const float fx = s.x > 0.0f ? s.x : 0.0f, fy = s.y > 0.0f ? s.y : 0.0f;
    const int x0 = static_cast<int>(fx) < w - 1 ? static_cast<int>(fx) : w - 1;
    const int y0 = static_cast<int>(fy) < h - 1 ? static_cast<int>(fy) : h - 1;
    const int x1 = x0 + 1 < w ? x0 + 1 : x0, y1 = y0 + 1 < h ? y0 + 1 : y0;
    const float ax = fx - static_cast<float>(x0) < 1.0f ? fx - static_cast<float>(x0) : 1.0f;
    const float ay = fy - static_cast<float>(y0) < 1.0f ? fy - static_cast<float>(y0) : 1.0f;
    const Rgb8 c00 = in(x0, y0), c10 = in(x1, y0), c01 = in(x0, y1), c11 = in(x1, y1);
    const auto mix = [&](uint8_t a, uint8_t b, uint8_t c, uint8_t d) {
      const float top = a + (b - a) * ax, bottom = c + (d - c) * ax;
      return static_cast<uint8_t>(top + (bottom - top) * ay + 0.5f);  // >= 0: rounds
    };
    out.data()[i] = {mix(c00.r, c10.r, c01.r, c11.r), mix(c00.g, c10.g, c01.g, c11.g),
                     mix(c00.b, c10.b, c01.b, c11.b)};
  });
  return out;
}

}  // namespace hivox

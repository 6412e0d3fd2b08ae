#include "hivox/core/camera.h"

#include <cmath>

#include <fmt/format.h>

#include "hivox/core/error.h"
#include "hivox/core/image.h"

namespace hivox {

PinholeCamera PinholeCamera::scaled(float factor) const {
  PinholeCamera c = *this;
  c.fx = fx * factor;
  c.fy = fy * factor;
  // Pixel centres are at integer coordinates: (u + 0.5) * factor - 0.5.
  c.cx = (cx + 0.5f) * factor - 0.5f;
  c.cy = (cy + 0.5f) * factor - 0.5f;
  c.width = static_cast<int>(std::lround(width * factor));
  c.height = static_cast<int>(std::lround(height * factor));
  return c;
}

PinholeCamera PinholeCamera::subsampled(int factor) const {
  PinholeCamera c = scaled(1.0f / static_cast<float>(factor));
  c.width = width / factor;
  c.height = height / factor;
  return c;
}

void PinholeCamera::validate(const std::string& what) const {
  if (!std::isfinite(fx) || fx <= 0.0f)
    fail(ErrorCode::InvalidArgument, "{}: fx must be a positive focal length in pixels, got {}",
         what, fx);
  if (!std::isfinite(fy) || fy == 0.0f)
    fail(ErrorCode::InvalidArgument,
         "{}: fy must be a non-zero focal length in pixels (negative is allowed), got {}", what,
         fy);
  if (!std::isfinite(cx) || !std::isfinite(cy))
    fail(ErrorCode::InvalidArgument, "{}: principal point must be finite, got ({}, {})", what, cx,
         cy);
  if (width <= 0 || height <= 0)
    fail(ErrorCode::InvalidArgument, "{}: image size must be positive, got {}x{}", what, width,
         height);
  if (width > kMaxImageSide || height > kMaxImageSide)
    fail(ErrorCode::InvalidArgument, "{}: image size {}x{} exceeds {} pixels a side", what, width,
         height, kMaxImageSide);
}

std::string PinholeCamera::to_string() const {
  return fmt::format("fx={:.3f} fy={:.3f} cx={:.3f} cy={:.3f} {}x{}", fx, fy, cx, cy, width,
                     height);
}

void LensDistortion::validate(const std::string& what) const {
  const float c[5] = {k1, k2, p1, p2, k3};
  const char* names[5] = {"k1", "k2", "p1", "p2", "k3"};
  for (int i = 0; i < 5; ++i)
    if (!std::isfinite(c[i]))
      fail(ErrorCode::InvalidArgument, "{}: distortion coefficient {} must be finite, got {}", what,
           names[i], c[i]);
}

std::string LensDistortion::to_string() const {
  if (none()) return "none";
  return fmt::format("k1={:g} k2={:g} p1={:g} p2={:g} k3={:g}", k1, k2, p1, p2, k3);
}

}  // namespace hivox

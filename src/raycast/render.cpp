#include "hivox/raycast/render.h"

#include <algorithm>
#include <cmath>

#include "core/parallel.h"

namespace hivox {

namespace {

uint8_t to_byte(float v) {
  return static_cast<uint8_t>(std::clamp(v, 0.0f, 1.0f) * 255.0f + 0.5f);
}

// Lambert + Blinn-Phong with a light at the camera, for a normal in the camera frame and the
// unit direction from the camera to the point.
float phong(const Vec3f& n_c, const Vec3f& view_c) {
  const float diffuse = std::max(0.0f, -dot(n_c, view_c));
  const float specular = std::pow(diffuse, 24.0f);
  return 0.15f + 0.7f * diffuse + 0.25f * specular;
}

template <typename Shade>
ColorImage shade_hits(const RaycastResult& r, Shade&& shade) {
  const int w = r.depth_m.width(), h = r.depth_m.height();
  ColorImage out(w, h);
  const Rigid3f T_cw = to_rigid3f(r.T_wc.inverse());
  parallel_for(h, [&](int64_t row) {
    const int y = static_cast<int>(row);
    for (int x = 0; x < w; ++x) {
      if (!r.hit(x, y)) continue;
      const Vec3f n_c = T_cw.rotate(r.normals_w(x, y));
      const Vec3f view_c = normalized(r.camera.ray(static_cast<float>(x), static_cast<float>(y)));
      out(x, y) = shade(x, y, n_c, view_c);
    }
  });
  return out;
}

}  // namespace

DepthExtent depth_extent(const DepthImage& depth_m) {
  float lo = INFINITY, hi = 0.0f;
  for (std::size_t i = 0; i < depth_m.size(); ++i) {
    const float d = depth_m.data()[i];
    if (d > 0.0f) {
      lo = std::min(lo, d);
      hi = std::max(hi, d);
    }
  }
  if (!std::isfinite(lo)) return {};
  return {lo, std::max(hi, lo + 1e-3f)};
}

Rgb8 depth_ramp_color(float t) {
  // A ramp through dark blue, cyan, green, yellow and red.
  static const float kStops[5][3] = {{0.10f, 0.10f, 0.45f},
                                     {0.10f, 0.65f, 0.90f},
                                     {0.25f, 0.80f, 0.30f},
                                     {0.95f, 0.85f, 0.20f},
                                     {0.85f, 0.15f, 0.10f}};
  t = std::clamp(t, 0.0f, 1.0f) * 4.0f;
  const int k = std::min(3, static_cast<int>(t));
  const float f = t - static_cast<float>(k);
  return {to_byte(kStops[k][0] + (kStops[k + 1][0] - kStops[k][0]) * f),
          to_byte(kStops[k][1] + (kStops[k + 1][1] - kStops[k][1]) * f),
          to_byte(kStops[k][2] + (kStops[k + 1][2] - kStops[k][2]) * f)};
}

ColorImage render_depth(const DepthImage& depth_m, float min_m, float max_m) {
  if (min_m <= 0.0f || max_m <= min_m) {
    const DepthExtent e = depth_extent(depth_m);
    min_m = e.min_m;
    max_m = e.max_m;
  }
  ColorImage out(depth_m.width(), depth_m.height());
  for (std::size_t i = 0; i < depth_m.size(); ++i) {
    const float d = depth_m.data()[i];
    if (!(d > 0.0f)) continue;
    out.data()[i] = depth_ramp_color((d - min_m) / (max_m - min_m));
  }
  return out;
}

ColorImage render_normals(const RaycastResult& r) {
  return shade_hits(r, [](int, int, const Vec3f& n, const Vec3f&) {
    return Rgb8{to_byte(0.5f + 0.5f * n.x), to_byte(0.5f - 0.5f * n.y), to_byte(0.5f - 0.5f * n.z)};
  });
}

ColorImage render_shaded(const RaycastResult& r) {
  return shade_hits(r, [](int, int, const Vec3f& n, const Vec3f& v) {
    const uint8_t g = to_byte(phong(n, v) * 0.85f);
    return Rgb8{g, g, g};
  });
}

ColorImage render_colors(const RaycastResult& r) {
  if (!r.has_color) return render_shaded(r);
  return shade_hits(r, [&](int x, int y, const Vec3f& n, const Vec3f& v) {
    const float s = 0.55f + 0.45f * std::max(0.0f, -dot(n, v));
    const Rgb8 c = r.colors(x, y);
    return Rgb8{to_byte(c.r / 255.0f * s), to_byte(c.g / 255.0f * s), to_byte(c.b / 255.0f * s)};
  });
}

Rgb8 level_color(int level) {
  static const Rgb8 kColors[] = {{220, 40, 30}, {245, 165, 20}, {60, 180, 60}, {50, 110, 220}};
  return kColors[std::clamp(level, 0, 3)];
}

ColorImage render_levels(const RaycastResult& r) {
  return shade_hits(r, [&](int x, int y, const Vec3f& n, const Vec3f& v) {
    const float s = 0.35f + 0.65f * std::max(0.0f, -dot(n, v));
    const Rgb8 c = level_color(r.levels(x, y));
    return Rgb8{to_byte(c.r / 255.0f * s), to_byte(c.g / 255.0f * s), to_byte(c.b / 255.0f * s)};
  });
}

}  // namespace hivox

#include "hivox/synth/render.h"

#include <algorithm>
#include <cmath>

#include "core/parallel.h"
#include "hivox/core/error.h"

namespace hivox {

namespace {

uint8_t to_byte(float v) {
  return static_cast<uint8_t>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
}

}  // namespace

RenderedFrame render(const SyntheticScene& scene, const PinholeCamera& camera, const Pose& T_wc,
                     double max_depth_m) {
  camera.validate("render camera");
  if (!(max_depth_m > 0.0))
    fail(ErrorCode::InvalidArgument, "render: max_depth_m must be > 0, got {}", max_depth_m);
  RenderedFrame out;
  out.T_wc = T_wc;
  out.depth_m.resize(camera.width, camera.height, 0.0f);
  out.color.resize(camera.width, camera.height, scene.lighting().background);
  out.normal_w.resize(camera.width, camera.height, Vec3f{});

  const Eigen::Matrix3d R_wc = T_wc.linear();
  const Eigen::Vector3d origin_w = T_wc.translation();
  const Lighting& light = scene.lighting();
  const double fx = camera.fx, fy = camera.fy, cx = camera.cx, cy = camera.cy;

  parallel_for_dynamic(camera.height, 4, [&](int64_t row) {
    const int v = static_cast<int>(row);
    for (int u = 0; u < camera.width; ++u) {
      // Ray with unit z in the camera frame: the hit's depth is its distance / |ray_c|.
      const Eigen::Vector3d ray_c((u - cx) / fx, (v - cy) / fy, 1.0);
      const double ray_len = ray_c.norm();
      const auto hit = scene.intersect(origin_w, R_wc * ray_c, max_depth_m * ray_len);
      if (!hit) continue;
      const double z = hit->t_m / ray_len;
      if (!(z > 0.0) || z > max_depth_m) continue;
      out.depth_m(u, v) = static_cast<float>(z);
      out.normal_w(u, v) = {static_cast<float>(hit->n_w.x()), static_cast<float>(hit->n_w.y()),
                            static_cast<float>(hit->n_w.z())};
      const Eigen::Vector3f c = hit->color * light.shade(hit->n_w);
      out.color(u, v) = {to_byte(c.x()), to_byte(c.y()), to_byte(c.z())};
    }
  });
  return out;
}

}  // namespace hivox

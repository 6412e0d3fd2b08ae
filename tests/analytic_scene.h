#pragma once
// A tiny exact scene for tests that must not depend on the code under test: a sphere resting
// above a floor plane, with closed-form ray intersection and signed distance.

#include <cmath>
#include <limits>

#include "hivox/core/camera.h"
#include "hivox/core/image.h"
#include "hivox/core/pose.h"

namespace hivox::test {

struct SphereOnPlane {
  Eigen::Vector3d centre{0.0, 0.0, 0.25};
  double radius = 0.2;
  double floor_z = 0.0;  // plane z = floor_z, free space above
  bool with_floor = true;

  /// Signed distance, positive in free space (exact: the solids are disjoint).
  double sdf(const Eigen::Vector3d& p) const {
    const double s = (p - centre).norm() - radius;
    return with_floor ? std::min(s, p.z() - floor_z) : s;
  }

  /// Ray parameter of the first hit (ray o + t d, |d| arbitrary), or +inf.
  double intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const {
    double best = std::numeric_limits<double>::infinity();
    const Eigen::Vector3d oc = o - centre;
    const double a = d.dot(d), b = 2 * oc.dot(d), c = oc.dot(oc) - radius * radius;
    const double disc = b * b - 4 * a * c;
    if (disc >= 0) {
      const double t = (-b - std::sqrt(disc)) / (2 * a);
      if (t > 0) best = t;
    }
    if (with_floor && std::abs(d.z()) > 1e-12) {
      const double t = (floor_z - o.z()) / d.z();
      if (t > 0 && t < best) best = t;
    }
    return best;
  }

  /// Exact depth image (z in the camera frame) seen from T_wc; 0 where nothing is hit.
  DepthImage render(const PinholeCamera& cam, const Pose& T_wc, double max_depth = 10.0) const {
    DepthImage depth(cam.width, cam.height, 0.0f);
    const Eigen::Vector3d o = T_wc.translation();
    for (int y = 0; y < cam.height; ++y)
      for (int x = 0; x < cam.width; ++x) {
        const Eigen::Vector3d ray_c((x - cam.cx) / cam.fx, (y - cam.cy) / cam.fy, 1.0);
        const double t = intersect(o, T_wc.linear() * ray_c);
        if (t < max_depth) depth(x, y) = static_cast<float>(t);  // ray_c has z = 1: t is depth
      }
    return depth;
  }
};

/// Camera poses on a circle around `target` at `radius` and `height` above it, looking at it.
inline std::vector<Pose> orbit(const Eigen::Vector3d& target, double radius, double height, int n,
                               double start_angle = 0.0, double sweep = 2 * M_PI) {
  std::vector<Pose> poses;
  for (int i = 0; i < n; ++i) {
    const double a = start_angle + sweep * i / n;
    const Eigen::Vector3d eye =
        target + Eigen::Vector3d(radius * std::cos(a), radius * std::sin(a), height);
    poses.push_back(look_at(eye, target, Eigen::Vector3d::UnitZ()));
  }
  return poses;
}

}  // namespace hivox::test

#pragma once
// Small meshes with known geometry for the mesh renderer's tests, and the exact ray queries
// against them computed here, independently of the renderer.

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "hivox/core/camera.h"
#include "hivox/core/pose.h"
#include "hivox/mesh/triangle_mesh.h"
#include "synth/render_test_util.h"

namespace hivox::test {

inline Vec3f vec3f(const Eigen::Vector3d& p) {
  return {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())};
}

/// A box with corners `center +- R half`, 8 vertices, 12 triangles (counter-clockwise from
/// outside). Its float vertices are exact when the inputs make them so.
inline TriangleMesh box_mesh(const Eigen::Vector3d& center, const Eigen::Vector3d& half,
                             const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  TriangleMesh m;
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d s((i & 1) ? 1 : -1, (i & 2) ? 1 : -1, (i & 4) ? 1 : -1);
    m.positions_w.push_back(vec3f(center + R * s.cwiseProduct(half)));
  }
  // Vertex index bits: x = 1, y = 2, z = 4.
  m.triangles = {{0, 2, 1}, {1, 2, 3},   // z-
                 {4, 5, 6}, {5, 7, 6},   // z+
                 {0, 1, 4}, {1, 5, 4},   // y-
                 {2, 6, 3}, {3, 6, 7},   // y+
                 {0, 4, 2}, {2, 4, 6},   // x-
                 {1, 3, 5}, {3, 7, 5}};  // x+
  return m;
}

/// Distance along the ray `o + t d` (t > 0) to where it enters the axis-aligned box
/// `[lo, hi]` (slab test), with the entered face's axis and sign; none when it misses.
struct BoxHit {
  double t = 0;
  int axis = 0;
  double sign = 0;  ///< outward normal = sign * e_axis
};
inline std::optional<BoxHit> ray_box(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                     const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  double t_in = 0, t_out = std::numeric_limits<double>::infinity();
  int axis = -1;
  double sign = 0;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0) {
      if (o[a] < lo[a] || o[a] > hi[a]) return std::nullopt;
      continue;
    }
    double t0 = (lo[a] - o[a]) / d[a], t1 = (hi[a] - o[a]) / d[a];
    double s = -1;  // entering through the low face
    if (t0 > t1) {
      std::swap(t0, t1);
      s = 1;
    }
    if (t0 > t_in) {
      t_in = t0;
      axis = a;
      sign = s;
    }
    t_out = std::min(t_out, t1);
  }
  if (axis < 0 || t_in > t_out) return std::nullopt;
  return BoxHit{t_in, axis, sign};
}

}  // namespace hivox::test

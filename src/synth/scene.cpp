#include "hivox/synth/scene.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "hivox/core/error.h"

namespace hivox {

namespace {

using Vec3 = Eigen::Vector3d;
constexpr double kInf = std::numeric_limits<double>::infinity();

double sign_of(double x) {
  return x < 0.0 ? -1.0 : 1.0;
}

// ---- Shape math in local frames --------------------------------------------------------------

// Signed distance of a (rounded) box centred at the origin, axis-aligned, outer half extents h.
double box_sdf_local(const Vec3& p, const Vec3& h, double r) {
  const Vec3 q = p.cwiseAbs() - (h - Vec3::Constant(r));
  return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0) - r;
}

Vec3 box_gradient_local(const Vec3& p, const Vec3& h, double r) {
  const Vec3 q = p.cwiseAbs() - (h - Vec3::Constant(r));
  if (q.maxCoeff() > 0.0) {
    Vec3 g = q.cwiseMax(0.0);
    for (int i = 0; i < 3; ++i) g[i] *= sign_of(p[i]);
    return g.normalized();
  }
  int axis = 0;
  q.maxCoeff(&axis);
  Vec3 g = Vec3::Zero();
  g[axis] = sign_of(p[axis]);
  return g;
}

// Slab test of the ray o + t d against the box |x_i| <= h_i. Returns false on a miss; otherwise
// the parameter interval [t_near, t_far] and the axis of the entry face.
bool slab_local(const Vec3& o, const Vec3& d, const Vec3& h, double* t_near, double* t_far,
                int* axis_near) {
  double t0 = -kInf, t1 = kInf;
  int axis = -1;
  for (int i = 0; i < 3; ++i) {
    if (d[i] == 0.0) {
      if (std::abs(o[i]) > h[i]) return false;
      continue;
    }
    const double inv = 1.0 / d[i];
    double ta = (-h[i] - o[i]) * inv;
    double tb = (h[i] - o[i]) * inv;
    if (ta > tb) std::swap(ta, tb);
    if (ta > t0) {
      t0 = ta;
      axis = i;
    }
    t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  *t_near = t0;
  *t_far = t1;
  *axis_near = axis;
  return true;
}

// First parameter t > 0 where the ray crosses the surface of the box |x_i| <= h_i.
std::optional<double> box_first_crossing_local(const Vec3& o, const Vec3& d, const Vec3& h) {
  double t0, t1;
  int axis;
  if (!slab_local(o, d, h, &t0, &t1, &axis)) return std::nullopt;
  if (t0 > 0.0) return t0;
  if (t1 > 0.0) return t1;
  return std::nullopt;
}

// Entry parameter (> 0) of the ray into a sphere; the exit when the origin is inside.
std::optional<double> sphere_first_crossing(const Vec3& o, const Vec3& d, const Vec3& c, double r) {
  const Vec3 oc = o - c;
  const double b = oc.dot(d);
  // r^2 - |oc - b d|^2 is the squared half chord; this form avoids cancellation in b^2 - c.
  const double h = r * r - (oc - b * d).squaredNorm();
  if (h < 0.0) return std::nullopt;
  const double s = std::sqrt(h);
  if (-b - s > 0.0) return -b - s;
  if (-b + s > 0.0) return -b + s;
  return std::nullopt;
}

// First crossing (> 0) of the side of a finite cylinder given in local coordinates: axis `a`,
// centre offset (cj, ck) in the other two axes, radius r, half length hl. Caps are ignored.
std::optional<double> cylinder_side_entry_local(const Vec3& o, const Vec3& d, int a, double cj,
                                                double ck, double r, double hl) {
  const int j = (a + 1) % 3, k = (a + 2) % 3;
  const double ox = o[j] - cj, oy = o[k] - ck;
  const double dx = d[j], dy = d[k];
  const double A = dx * dx + dy * dy;
  if (A < 1e-24) return std::nullopt;
  const double B = ox * dx + oy * dy;
  const double C = ox * ox + oy * oy - r * r;
  const double disc = B * B - A * C;
  if (disc < 0.0) return std::nullopt;
  const double t = (-B - std::sqrt(disc)) / A;
  if (t <= 0.0) return std::nullopt;
  if (std::abs(o[a] + t * d[a]) > hl) return std::nullopt;
  return t;
}

// Entry into a rounded box (outer half extents h, radius r > 0) from free space: the box is the
// union of three slabs, twelve edge cylinders and eight corner spheres, so its first entry is
// the smallest entry into any of them.
std::optional<double> rounded_box_entry_local(const Vec3& o, const Vec3& d, const Vec3& h,
                                              double r) {
  double t0, t1;
  int axis;
  if (!slab_local(o, d, h, &t0, &t1, &axis) || t1 <= 0.0) return std::nullopt;
  const Vec3 b = h - Vec3::Constant(r);
  if (t0 > 0.0) {
    // Fast path: the entry point on the outer box lies on the flat part of a face. (An origin
    // inside the outer box but outside the rounded one, near an edge, takes the slow path.)
    const Vec3 p = o + t0 * d;
    bool flat = true;
    for (int i = 0; i < 3; ++i)
      if (i != axis && std::abs(p[i]) > b[i]) flat = false;
    if (flat) return t0;
  }

  double best = kInf;
  for (int i = 0; i < 3; ++i) {
    Vec3 hi = b;
    hi[i] += r;
    if (auto t = box_first_crossing_local(o, d, hi); t && *t < best) best = *t;
  }
  for (int a = 0; a < 3; ++a) {
    const int j = (a + 1) % 3, k = (a + 2) % 3;
    for (double sj : {-1.0, 1.0})
      for (double sk : {-1.0, 1.0})
        if (auto t = cylinder_side_entry_local(o, d, a, sj * b[j], sk * b[k], r, b[a]);
            t && *t < best)
          best = *t;
  }
  for (double sx : {-1.0, 1.0})
    for (double sy : {-1.0, 1.0})
      for (double sz : {-1.0, 1.0})
        if (auto t = sphere_first_crossing(o, d, Vec3(sx * b.x(), sy * b.y(), sz * b.z()), r);
            t && *t < best)
          best = *t;
  if (best == kInf) return std::nullopt;
  return best;
}

// ---- Per-shape dispatch ------------------------------------------------------------------------

double sdf_of(const Plane& s, const Vec3& p) {
  return s.normal_w.dot(p - s.point_w);
}
double sdf_of(const Box& s, const Vec3& p) {
  return box_sdf_local(s.R_wb.transpose() * (p - s.center_w), s.half_extents_m, s.corner_radius_m);
}
double sdf_of(const Sphere& s, const Vec3& p) {
  return (p - s.center_w).norm() - s.radius_m;
}
double sdf_of(const Cylinder& s, const Vec3& p) {
  const Vec3 v = p - s.center_w;
  const double a = v.dot(s.axis_w);
  const double rho = (v - a * s.axis_w).norm();
  const double dx = rho - s.radius_m, dy = std::abs(a) - s.half_height_m;
  return std::min(std::max(dx, dy), 0.0) + std::hypot(std::max(dx, 0.0), std::max(dy, 0.0));
}
double sdf_of(const Room& s, const Vec3& p) {
  const Vec3 c = 0.5 * (s.min_w + s.max_w), h = 0.5 * (s.max_w - s.min_w);
  return -box_sdf_local(p - c, h, 0.0);
}

Vec3 normal_of(const Plane& s, const Vec3&) {
  return s.normal_w;
}
Vec3 normal_of(const Box& s, const Vec3& p) {
  return s.R_wb * box_gradient_local(s.R_wb.transpose() * (p - s.center_w), s.half_extents_m,
                                     s.corner_radius_m);
}
Vec3 normal_of(const Sphere& s, const Vec3& p) {
  const Vec3 v = p - s.center_w;
  const double n = v.norm();
  return n > 0.0 ? Vec3(v / n) : Vec3(Vec3::UnitZ());
}
Vec3 normal_of(const Cylinder& s, const Vec3& p) {
  const Vec3 v = p - s.center_w;
  const double a = v.dot(s.axis_w);
  const Vec3 radial = v - a * s.axis_w;
  const double rho = radial.norm();
  const Vec3 radial_unit = rho > 0.0 ? Vec3(radial / rho) : s.axis_w.unitOrthogonal();
  const double dx = rho - s.radius_m, dy = std::abs(a) - s.half_height_m;
  const Vec3 axial_unit = sign_of(a) * s.axis_w;
  if (dx > 0.0 || dy > 0.0)
    return (std::max(dx, 0.0) * radial_unit + std::max(dy, 0.0) * axial_unit).normalized();
  return dx > dy ? radial_unit : axial_unit;
}
Vec3 normal_of(const Room& s, const Vec3& p) {
  const Vec3 c = 0.5 * (s.min_w + s.max_w), h = 0.5 * (s.max_w - s.min_w);
  return -box_gradient_local(p - c, h, 0.0);
}

std::optional<double> intersect_of(const Plane& s, const Vec3& o, const Vec3& d) {
  const double denom = s.normal_w.dot(d);
  const double dist = s.normal_w.dot(o - s.point_w);
  if (denom >= 0.0 || dist < 0.0) return std::nullopt;
  return -dist / denom;
}
std::optional<double> intersect_of(const Box& s, const Vec3& o, const Vec3& d) {
  const Vec3 o_b = s.R_wb.transpose() * (o - s.center_w);
  const Vec3 d_b = s.R_wb.transpose() * d;
  if (s.corner_radius_m > 0.0)
    return rounded_box_entry_local(o_b, d_b, s.half_extents_m, s.corner_radius_m);
  return box_first_crossing_local(o_b, d_b, s.half_extents_m);
}
std::optional<double> intersect_of(const Sphere& s, const Vec3& o, const Vec3& d) {
  return sphere_first_crossing(o, d, s.center_w, s.radius_m);
}
std::optional<double> intersect_of(const Cylinder& s, const Vec3& o, const Vec3& d) {
  const Vec3 ov = o - s.center_w;
  const double oa = ov.dot(s.axis_w), da = d.dot(s.axis_w);
  const Vec3 o_r = ov - oa * s.axis_w, d_r = d - da * s.axis_w;
  const double r2 = s.radius_m * s.radius_m, h = s.half_height_m;
  double best = kInf;
  const double A = d_r.squaredNorm();
  if (A > 1e-24) {
    const double B = o_r.dot(d_r), C = o_r.squaredNorm() - r2;
    const double disc = B * B - A * C;
    if (disc >= 0.0) {
      const double sq = std::sqrt(disc);
      for (double t : {(-B - sq) / A, (-B + sq) / A})
        if (t > 0.0 && t < best && std::abs(oa + t * da) <= h) best = t;
    }
  }
  if (std::abs(da) > 1e-24) {
    for (double cap : {-h, h}) {
      const double t = (cap - oa) / da;
      if (t > 0.0 && t < best && (o_r + t * d_r).squaredNorm() <= r2) best = t;
    }
  }
  if (best == kInf) return std::nullopt;
  return best;
}
std::optional<double> intersect_of(const Room& s, const Vec3& o, const Vec3& d) {
  double t = kInf;
  for (int i = 0; i < 3; ++i) {
    if (!(o[i] > s.min_w[i] && o[i] < s.max_w[i])) return std::nullopt;  // origin in the walls
    if (d[i] > 0.0) t = std::min(t, (s.max_w[i] - o[i]) / d[i]);
    if (d[i] < 0.0) t = std::min(t, (s.min_w[i] - o[i]) / d[i]);
  }
  if (t == kInf) return std::nullopt;
  return t;
}

Aabb bounds_of(const Plane&) {
  return {};
}
Aabb bounds_of(const Box& s) {
  const Vec3 e = s.R_wb.cwiseAbs() * s.half_extents_m;
  return {s.center_w - e, s.center_w + e};
}
Aabb bounds_of(const Sphere& s) {
  return {s.center_w - Vec3::Constant(s.radius_m), s.center_w + Vec3::Constant(s.radius_m)};
}
Aabb bounds_of(const Cylinder& s) {
  Vec3 e;
  for (int i = 0; i < 3; ++i) {
    const double a = s.axis_w[i];
    e[i] = s.half_height_m * std::abs(a) + s.radius_m * std::sqrt(std::max(0.0, 1.0 - a * a));
  }
  return {s.center_w - e, s.center_w + e};
}
Aabb bounds_of(const Room&) {
  return {};
}

bool is_unit(const Vec3& v) {
  return v.allFinite() && std::abs(v.norm() - 1.0) < 1e-6;
}
bool positive(double x) {
  return std::isfinite(x) && x > 0.0;
}

void validate_of(const Plane& s) {
  if (!s.point_w.allFinite()) fail(ErrorCode::InvalidArgument, "plane: point_w must be finite");
  if (!is_unit(s.normal_w))
    fail(ErrorCode::InvalidArgument, "plane: normal_w must be a unit vector, has norm {}",
         s.normal_w.norm());
}
void validate_of(const Box& s) {
  if (!s.center_w.allFinite()) fail(ErrorCode::InvalidArgument, "box: center_w must be finite");
  if (!(s.half_extents_m.array() > 0.0).all() || !s.half_extents_m.allFinite())
    fail(ErrorCode::InvalidArgument, "box: half_extents_m must be positive, got ({}, {}, {})",
         s.half_extents_m.x(), s.half_extents_m.y(), s.half_extents_m.z());
  if (!s.R_wb.allFinite() ||
      !(s.R_wb.transpose() * s.R_wb).isApprox(Eigen::Matrix3d::Identity(), 1e-6) ||
      s.R_wb.determinant() < 0.0)
    fail(ErrorCode::InvalidArgument, "box: R_wb must be a rotation matrix");
  if (!(s.corner_radius_m >= 0.0) || s.corner_radius_m > s.half_extents_m.minCoeff())
    fail(ErrorCode::InvalidArgument,
         "box: corner_radius_m must be in [0, smallest half extent = {}], got {}",
         s.half_extents_m.minCoeff(), s.corner_radius_m);
}
void validate_of(const Sphere& s) {
  if (!s.center_w.allFinite()) fail(ErrorCode::InvalidArgument, "sphere: center_w must be finite");
  if (!positive(s.radius_m))
    fail(ErrorCode::InvalidArgument, "sphere: radius_m must be > 0, got {}", s.radius_m);
}
void validate_of(const Cylinder& s) {
  if (!s.center_w.allFinite())
    fail(ErrorCode::InvalidArgument, "cylinder: center_w must be finite");
  if (!is_unit(s.axis_w))
    fail(ErrorCode::InvalidArgument, "cylinder: axis_w must be a unit vector, has norm {}",
         s.axis_w.norm());
  if (!positive(s.radius_m))
    fail(ErrorCode::InvalidArgument, "cylinder: radius_m must be > 0, got {}", s.radius_m);
  if (!positive(s.half_height_m))
    fail(ErrorCode::InvalidArgument, "cylinder: half_height_m must be > 0, got {}",
         s.half_height_m);
}
void validate_of(const Room& s) {
  if (!s.min_w.allFinite() || !s.max_w.allFinite() || !(s.min_w.array() < s.max_w.array()).all())
    fail(ErrorCode::InvalidArgument, "room: min_w must be finite and below max_w on every axis");
}

// Ray against an AABB: [t_enter, t_exit] within [0, t_max], using the inverse direction. On
// plain arrays: the BVH walk calls this for every node a ray visits, and under the sanitizers
// clang left each of Eigen's indexed reads a call (8 % of a tracking test under ASan + UBSan).
bool ray_box(const Aabb& box, const double o[3], const double inv_d[3], double t_max,
             double* t_enter) {
  const double* lo = box.min_w.data();
  const double* hi = box.max_w.data();
  double t0 = 0.0, t1 = t_max;
  for (int i = 0; i < 3; ++i) {
    double ta = (lo[i] - o[i]) * inv_d[i];
    double tb = (hi[i] - o[i]) * inv_d[i];
    if (ta > tb) std::swap(ta, tb);
    // NaN (0 * inf when the origin lies on a slab plane of a parallel ray) keeps the interval.
    if (ta > t0) t0 = ta;
    if (tb < t1) t1 = tb;
    if (t0 > t1) return false;
  }
  *t_enter = t0;
  return true;
}

}  // namespace

// ---- Public shape functions --------------------------------------------------------------------

double sdf(const Shape& shape, const Eigen::Vector3d& p_w) {
  return std::visit([&](const auto& s) { return sdf_of(s, p_w); }, shape);
}

Eigen::Vector3d normal(const Shape& shape, const Eigen::Vector3d& p_w) {
  return std::visit([&](const auto& s) { return normal_of(s, p_w); }, shape);
}

std::optional<double> intersect(const Shape& shape, const Eigen::Vector3d& origin_w,
                                const Eigen::Vector3d& dir_w, double t_max) {
  const auto t = std::visit([&](const auto& s) { return intersect_of(s, origin_w, dir_w); }, shape);
  if (t && *t <= t_max) return t;
  return std::nullopt;
}

Aabb bounds(const Shape& shape) {
  return std::visit([](const auto& s) { return bounds_of(s); }, shape);
}

void validate(const Shape& shape) {
  std::visit([](const auto& s) { validate_of(s); }, shape);
}

std::string_view shape_kind(const Shape& shape) {
  static constexpr std::array<std::string_view, 5> kNames = {"plane", "box", "sphere", "cylinder",
                                                             "room"};
  return kNames[shape.index()];
}

// ---- Material --------------------------------------------------------------------------------

Eigen::Vector3f Material::color_at(const Eigen::Vector3d& p_w) const {
  if (texture == Texture::Plain || !(texture_period_m > 0.0)) return albedo;
  // The 0.5013 offset keeps cell borders away from surfaces at round coordinates (a wall at
  // x = 2.0 with 0.25 m cells would otherwise flicker between two cells).
  constexpr double kOffset = 0.5013;
  long parity = 0;
  if (texture == Texture::Checker) {
    for (int i = 0; i < 3; ++i)
      parity += static_cast<long>(std::floor(p_w[i] / texture_period_m + kOffset));
  } else {
    parity = static_cast<long>(std::floor(p_w.dot(stripe_axis_w) / texture_period_m + kOffset));
  }
  return (parity & 1) ? albedo2 : albedo;
}

// ---- Scene -------------------------------------------------------------------------------------

int SyntheticScene::add(const Shape& shape, const Material& material, std::string label) {
  validate(shape);
  if (!(material.texture_period_m > 0.0) && material.texture != Texture::Plain)
    fail(ErrorCode::InvalidArgument, "material: texture_period_m must be > 0, got {}",
         material.texture_period_m);
  primitives_.push_back({shape, material, std::move(label)});
  rebuild_bvh();
  return static_cast<int>(primitives_.size()) - 1;
}

void SyntheticScene::set_camera_path(const CameraPath& path) {
  path.validate();
  camera_path_ = path;
}

void SyntheticScene::set_lighting(const Lighting& lighting) {
  if (!is_unit(lighting.to_light_w))
    fail(ErrorCode::InvalidArgument, "lighting: to_light_w must be a unit vector, has norm {}",
         lighting.to_light_w.norm());
  if (!(lighting.ambient >= 0.0f && lighting.ambient <= 1.0f))
    fail(ErrorCode::InvalidArgument, "lighting: ambient must be in [0, 1], got {}",
         lighting.ambient);
  lighting_ = lighting;
}

void SyntheticScene::rebuild_bvh() {
  unbounded_.clear();
  bvh_items_.clear();
  item_bounds_.clear();
  bvh_.clear();
  for (std::size_t i = 0; i < primitives_.size(); ++i) {
    Aabb b = bounds(primitives_[i].shape);
    if (!b.empty()) {
      // A hair of padding keeps rays that graze a box face from missing it by round-off.
      b.min_w.array() -= 1e-9;
      b.max_w.array() += 1e-9;
      bvh_items_.push_back(static_cast<int>(i));
    } else {
      unbounded_.push_back(static_cast<int>(i));
    }
    item_bounds_.push_back(b);
  }
  if (!bvh_items_.empty()) build_node(0, static_cast<int>(bvh_items_.size()));
}

int SyntheticScene::build_node(int first, int count) {
  const int index = static_cast<int>(bvh_.size());
  bvh_.emplace_back();
  Aabb box, centroids;
  for (int i = first; i < first + count; ++i) {
    box.extend(item_bounds_[bvh_items_[i]]);
    centroids.extend(item_bounds_[bvh_items_[i]].center());
  }
  bvh_[index].box = box;
  constexpr int kLeafSize = 2;
  if (count <= kLeafSize) {
    bvh_[index].first = first;
    bvh_[index].count = count;
    return index;
  }
  int axis = 0;
  centroids.size().maxCoeff(&axis);
  const int mid = first + count / 2;
  std::nth_element(bvh_items_.begin() + first, bvh_items_.begin() + mid,
                   bvh_items_.begin() + first + count, [&](int a, int b) {
                     return item_bounds_[a].center()[axis] < item_bounds_[b].center()[axis];
                   });
  const int left = build_node(first, mid - first);
  const int right = build_node(mid, first + count - mid);
  bvh_[index].left = left;
  bvh_[index].right = right;
  return index;
}

double SyntheticScene::sdf_and_closest(const Eigen::Vector3d& p_w, int* closest) const {
  double best = kInf;
  int best_index = -1;
  for (int i : unbounded_) {
    const double d = hivox::sdf(primitives_[i].shape, p_w);
    if (d < best) {
      best = d;
      best_index = i;
    }
  }
  if (!bvh_.empty()) {
    std::array<int, 64> stack;
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const BvhNode& node = bvh_[stack[--top]];
      // Outside a node's box, every primitive in it is at least that far away.
      const double box_distance = node.box.distance(p_w);
      if (box_distance > 0.0 && box_distance >= best) continue;
      if (node.left < 0) {
        for (int k = node.first; k < node.first + node.count; ++k) {
          const int i = bvh_items_[k];
          const double d = hivox::sdf(primitives_[i].shape, p_w);
          if (d < best) {
            best = d;
            best_index = i;
          }
        }
        continue;
      }
      // Visit the nearer child first (pushed last) so that pruning bites early.
      const double dl = bvh_[node.left].box.distance(p_w);
      const double dr = bvh_[node.right].box.distance(p_w);
      if (dl <= dr) {
        stack[top++] = node.right;
        stack[top++] = node.left;
      } else {
        stack[top++] = node.left;
        stack[top++] = node.right;
      }
    }
  }
  if (closest) *closest = best_index;
  return best;
}

double SyntheticScene::sdf(const Eigen::Vector3d& p_w) const {
  return sdf_and_closest(p_w, nullptr);
}

int SyntheticScene::closest_primitive(const Eigen::Vector3d& p_w) const {
  int closest = -1;
  sdf_and_closest(p_w, &closest);
  return closest;
}

Eigen::Vector3d SyntheticScene::normal(const Eigen::Vector3d& p_w) const {
  const int i = closest_primitive(p_w);
  if (i < 0) return Vec3::UnitZ();
  return hivox::normal(primitives_[i].shape, p_w);
}

std::optional<Hit> SyntheticScene::intersect(const Eigen::Vector3d& origin_w,
                                             const Eigen::Vector3d& dir_w, double t_max_m) const {
  const double len = dir_w.norm();
  if (!(len > 0.0) || !std::isfinite(len)) return std::nullopt;
  const Vec3 d = dir_w / len;
  double best = t_max_m;
  int best_index = -1;
  for (int i : unbounded_) {
    if (auto t = hivox::intersect(primitives_[i].shape, origin_w, d, best); t) {
      best = *t;
      best_index = i;
    }
  }
  if (!bvh_.empty()) {
    const double o[3] = {origin_w.x(), origin_w.y(), origin_w.z()};
    const double inv_d[3] = {1.0 / d.x(), 1.0 / d.y(), 1.0 / d.z()};
    struct Pending {
      int node;
      double t_enter;
    };
    std::array<Pending, 64> stack;
    int top = 0;
    double t_root = 0;
    if (ray_box(bvh_[0].box, o, inv_d, best, &t_root)) stack[top++] = {0, t_root};
    while (top > 0) {
      const Pending pending = stack[--top];
      if (pending.t_enter > best) continue;  // a nearer hit was found since it was pushed
      const BvhNode& node = bvh_[pending.node];
      if (node.left < 0) {
        for (int k = node.first; k < node.first + node.count; ++k) {
          const int i = bvh_items_[k];
          if (auto t = hivox::intersect(primitives_[i].shape, origin_w, d, best); t) {
            best = *t;
            best_index = i;
          }
        }
        continue;
      }
      double tl = 0, tr = 0;
      const bool hit_l = ray_box(bvh_[node.left].box, o, inv_d, best, &tl);
      const bool hit_r = ray_box(bvh_[node.right].box, o, inv_d, best, &tr);
      if (hit_l && hit_r) {
        // Nearer child on top of the stack.
        if (tl <= tr) {
          stack[top++] = {node.right, tr};
          stack[top++] = {node.left, tl};
        } else {
          stack[top++] = {node.left, tl};
          stack[top++] = {node.right, tr};
        }
      } else if (hit_l) {
        stack[top++] = {node.left, tl};
      } else if (hit_r) {
        stack[top++] = {node.right, tr};
      }
    }
  }
  if (best_index < 0) return std::nullopt;
  Hit hit;
  hit.t_m = best;
  hit.p_w = origin_w + best * d;
  hit.primitive = best_index;
  const Primitive& prim = primitives_[best_index];
  hit.n_w = hivox::normal(prim.shape, hit.p_w);
  hit.color = prim.material.color_at(hit.p_w);
  return hit;
}

Aabb SyntheticScene::content_bounds() const {
  if (content_bounds_) return *content_bounds_;
  Aabb all;
  for (const Primitive& p : primitives_) {
    if (const auto* room = std::get_if<Room>(&p.shape)) {
      all.extend(room->min_w);
      all.extend(room->max_w);
    } else {
      all.extend(bounds(p.shape));
    }
  }
  return all;
}

}  // namespace hivox

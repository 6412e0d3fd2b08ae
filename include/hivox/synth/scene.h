#pragma once
/// @file
/// Analytic synthetic scenes: primitives with exact signed distance functions (SDF) and exact
/// ray intersections, grouped under a bounding-volume hierarchy so queries stay fast.
///
/// Conventions: metres; the world is z-up (floor at z = 0 in the indoor scenes); the SDF is
/// positive in free space and negative inside solids. A scene is the union of its primitives'
/// solids; its SDF is the minimum of theirs, which is **exact everywhere in free space** (the
/// distance to a union of sets is the minimum of the distances). Inside a solid it is exact
/// where that point lies in one primitive only and its nearest surface point is not covered by
/// another; where solids overlap or touch (table legs on the floor, keys on the keyboard base,
/// bumps on the blob) it is a bound: |returned| <= |true distance|, with the right sign.

#include <algorithm>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <Eigen/Core>

#include "hivox/core/image.h"
#include "hivox/synth/trajectory.h"

namespace hivox {

/// Axis-aligned bounding box `[min_w, max_w]`; empty when any min > max (the default).
struct Aabb {
  Eigen::Vector3d min_w = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d max_w = Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity());

  bool empty() const { return (min_w.array() > max_w.array()).any(); }
  Eigen::Vector3d center() const { return 0.5 * (min_w + max_w); }
  Eigen::Vector3d size() const { return max_w - min_w; }
  bool contains(const Eigen::Vector3d& p_w) const {
    return (p_w.array() >= min_w.array()).all() && (p_w.array() <= max_w.array()).all();
  }
  void extend(const Eigen::Vector3d& p_w) {
    min_w = min_w.cwiseMin(p_w);
    max_w = max_w.cwiseMax(p_w);
  }
  void extend(const Aabb& b) {
    min_w = min_w.cwiseMin(b.min_w);
    max_w = max_w.cwiseMax(b.max_w);
  }
  /// Euclidean distance from `p_w` to the box (0 inside).
  double distance(const Eigen::Vector3d& p_w) const {
    return (min_w - p_w).cwiseMax(p_w - max_w).cwiseMax(0.0).norm();
  }
};

// ---- Shapes ----------------------------------------------------------------------------------
// Each shape is a solid; its surface normal points out of the solid into free space.

/// Half-space: the solid lies behind the plane (opposite `normal_w`); free space in front.
struct Plane {
  Eigen::Vector3d point_w = Eigen::Vector3d::Zero();    ///< any point on the plane
  Eigen::Vector3d normal_w = Eigen::Vector3d::UnitZ();  ///< unit normal, into free space
};

/// Box, optionally rotated and with rounded edges (a box of half extents
/// `half_extents_m - corner_radius_m` grown by a sphere of radius `corner_radius_m`).
struct Box {
  Eigen::Vector3d center_w = Eigen::Vector3d::Zero();
  Eigen::Vector3d half_extents_m = Eigen::Vector3d::Constant(0.1);  ///< outer half sizes
  Eigen::Matrix3d R_wb = Eigen::Matrix3d::Identity();  ///< box axes in the world (rotation)
  double corner_radius_m = 0;  ///< edge rounding, 0 = sharp; <= the smallest half extent
};

struct Sphere {
  Eigen::Vector3d center_w = Eigen::Vector3d::Zero();
  double radius_m = 0.1;
};

/// Solid cylinder with flat caps.
struct Cylinder {
  Eigen::Vector3d center_w = Eigen::Vector3d::Zero();  ///< centre of the axis segment
  Eigen::Vector3d axis_w = Eigen::Vector3d::UnitZ();   ///< unit axis direction
  double radius_m = 0.05;
  double half_height_m = 0.05;  ///< half the length along the axis
};

/// The inside of an axis-aligned box is free space; everything outside it is solid (walls,
/// floor and ceiling of a room). Normals point into the room.
struct Room {
  Eigen::Vector3d min_w = Eigen::Vector3d(-2, -2, 0);
  Eigen::Vector3d max_w = Eigen::Vector3d(2, 2, 2.5);
};

using Shape = std::variant<Plane, Box, Sphere, Cylinder, Room>;

/// Exact signed distance from `p_w` to the shape's surface, metres (positive outside the solid).
double sdf(const Shape& shape, const Eigen::Vector3d& p_w);
/// Unit gradient of the SDF at `p_w` (the outward surface normal on the surface). Where the
/// gradient is not unique (on the medial axis) one of the candidates is returned.
Eigen::Vector3d normal(const Shape& shape, const Eigen::Vector3d& p_w);
/// Distance `t` (metres) along the unit direction `dir_w` from `origin_w` to the first point
/// where the ray enters the solid, if it does so with `0 < t <= t_max`. `origin_w` must lie in
/// free space (sdf > 0); from inside a solid the result is unspecified.
std::optional<double> intersect(const Shape& shape, const Eigen::Vector3d& origin_w,
                                const Eigen::Vector3d& dir_w, double t_max);
/// Bounding box of the shape's surface; empty for unbounded shapes (Plane, Room: their solid is
/// infinite, so they are tested on every query).
Aabb bounds(const Shape& shape);
/// Throws `Error(InvalidArgument)` naming the bad field (non-unit normal, radius <= 0, ...).
void validate(const Shape& shape);
/// Short name of the shape kind: "plane", "box", "sphere", "cylinder", "room".
std::string_view shape_kind(const Shape& shape);

// ---- Materials -------------------------------------------------------------------------------

enum class Texture {
  Plain,    ///< `albedo` everywhere
  Checker,  ///< 3D checkerboard of `albedo` / `albedo2` cubes of side `texture_period_m`
  Stripes,  ///< stripes of width `texture_period_m` along `stripe_axis_w`
};

/// Surface colour. Procedural textures are functions of the world point, so a surface keeps its
/// pattern in every frame (what colour integration needs to show).
struct Material {
  Eigen::Vector3f albedo = Eigen::Vector3f(0.7f, 0.7f, 0.7f);   ///< linear RGB in [0, 1]
  Eigen::Vector3f albedo2 = Eigen::Vector3f(0.4f, 0.4f, 0.4f);  ///< second texture colour
  Texture texture = Texture::Plain;
  double texture_period_m = 0.1;  ///< checker cube side / stripe width, metres
  Eigen::Vector3d stripe_axis_w = Eigen::Vector3d::UnitX();

  /// Unshaded colour at a surface point, linear RGB in [0, 1].
  Eigen::Vector3f color_at(const Eigen::Vector3d& p_w) const;
};

/// A shape with its material and a label naming the object it belongs to ("wall", "table",
/// "keyboard", "blob", ...), so tests can ask which object a point or block is near.
struct Primitive {
  Shape shape;
  Material material;
  std::string label;
};

/// What a ray hits first.
struct Hit {
  double t_m = 0;         ///< distance along the (normalised) ray direction, metres
  Eigen::Vector3d p_w;    ///< hit point
  Eigen::Vector3d n_w;    ///< unit surface normal, pointing into free space
  Eigen::Vector3f color;  ///< unshaded material colour at `p_w`, linear RGB in [0, 1]
  int primitive = -1;     ///< index into `SyntheticScene::primitives()`
};

/// Fixed light for Lambertian shading (view-independent, so colour is consistent across frames).
struct Lighting {
  Eigen::Vector3d to_light_w = Eigen::Vector3d(0.3, -0.5, 1.0).normalized();  ///< unit
  float ambient = 0.35f;        ///< fraction of the albedo lit regardless of orientation
  Rgb8 background{40, 40, 48};  ///< colour of pixels whose ray hits nothing

  /// The fraction of an albedo a surface with unit normal `n_w` shows:
  /// ambient + (1 - ambient) max(0, n . to_light).
  float shade(const Eigen::Vector3d& n_w) const {
    const float lambert = static_cast<float>(std::max(0.0, n_w.dot(to_light_w)));
    return ambient + (1.0f - ambient) * lambert;
  }
};

/// A union of primitives with exact SDF, normal and ray queries.
class SyntheticScene {
 public:
  SyntheticScene() = default;
  explicit SyntheticScene(std::string name) : name_(std::move(name)) {}

  /// Adds a primitive (validated; throws `Error(InvalidArgument)`) and returns its index.
  int add(const Shape& shape, const Material& material = {}, std::string label = "");

  const std::string& name() const { return name_; }
  const std::vector<Primitive>& primitives() const { return primitives_; }

  /// Signed distance of the union, metres; positive in free space. Exact in free space (see the
  /// file comment for inside solids). Infinity for an empty scene.
  double sdf(const Eigen::Vector3d& p_w) const;
  /// Index of the primitive whose SDF is smallest at `p_w` (the surface nearest to a point in
  /// free space), or -1 for an empty scene.
  int closest_primitive(const Eigen::Vector3d& p_w) const;
  /// Unit SDF gradient at `p_w`: the outward normal of the closest primitive.
  Eigen::Vector3d normal(const Eigen::Vector3d& p_w) const;
  /// First surface hit by the ray `origin_w + t * dir_w / |dir_w|` with `0 < t <= t_max_m`.
  /// `origin_w` must be in free space.
  std::optional<Hit> intersect(const Eigen::Vector3d& origin_w, const Eigen::Vector3d& dir_w,
                               double t_max_m = std::numeric_limits<double>::infinity()) const;

  /// Box around the content worth reconstructing (the room for indoor scenes, the object for
  /// single-object scenes). Defaults to the bounds of all bounded primitives and rooms.
  Aabb content_bounds() const;
  void set_content_bounds(const Aabb& bounds) { content_bounds_ = bounds; }

  /// The scene's camera path (see trajectory.h).
  const CameraPath& camera_path() const { return camera_path_; }
  void set_camera_path(const CameraPath& path);

  const Lighting& lighting() const { return lighting_; }
  /// Throws `Error(InvalidArgument)` for a non-unit light direction or ambient outside [0, 1].
  void set_lighting(const Lighting& lighting);

 private:
  struct BvhNode {
    Aabb box;
    int left = -1;  ///< child node index, or -1 for a leaf
    int right = -1;
    int first = 0;  ///< leaf: first index into `bvh_items_`
    int count = 0;  ///< leaf: number of primitives
  };
  void rebuild_bvh();
  int build_node(int first, int count);
  /// min over primitives of sdf, with the arg-min.
  double sdf_and_closest(const Eigen::Vector3d& p_w, int* closest) const;

  std::string name_;
  std::vector<Primitive> primitives_;
  std::vector<int> unbounded_;     ///< primitives tested on every query (planes, rooms)
  std::vector<int> bvh_items_;     ///< bounded primitives, in BVH leaf order
  std::vector<Aabb> item_bounds_;  ///< per primitive (empty for unbounded ones)
  std::vector<BvhNode> bvh_;
  std::optional<Aabb> content_bounds_;
  CameraPath camera_path_;
  Lighting lighting_;
};

/// Names accepted by `make_scene`: room, box, spheres, keyboard, blob, desk.
std::vector<std::string> scene_names();

/// A built-in scene (sizes of a real office, in metres, z up):
/// - `room`: 4.0 x 3.2 x 2.5 m room with a 1.4 x 0.7 m table (top at 0.75 m); large flat areas.
/// - `box`: a 0.30 x 0.20 x 0.16 m box with rounded edges, floating in empty space.
/// - `spheres`: five disjoint spheres of radius 3-12 cm, floating in empty space.
/// - `keyboard`: a 45 x 15 cm keyboard: 15 mm keys, 4 mm gaps, on a 15 mm base; fine structure.
/// - `blob`: a bumpy organic blob (~22 cm): a core sphere and 90 spheres of radius 1-4 cm.
/// - `desk`: the room with the table, keyboard, blob, a box, a monitor, a mug and spheres
///   (the default demo scene).
/// Indoor scenes come with an arc in front of the table; single objects with a full orbit.
/// Throws `Error(InvalidArgument)` listing the valid names for an unknown name.
SyntheticScene make_scene(std::string_view name);

}  // namespace hivox

#pragma once
/// @file
/// Exact rendering of a triangle mesh through a pinhole camera (Embree ray casting): depth (z
/// along the optical axis, metres), colour and world-frame normals, with the same conventions as
/// the analytic renderer (`hivox/synth/render.h`), so a mesh and an analytic scene of the same
/// surfaces give the same frames.
///
/// Embree is private to this module: this header does not include it.

#include <cstdint>
#include <memory>

#include "hivox/core/camera.h"
#include "hivox/core/pose.h"
#include "hivox/mesh/triangle_mesh.h"
#include "hivox/synth/render.h"
#include "hivox/synth/scene.h"

namespace hivox {

class MeshScene;
enum class MeshRayMode;

/// Renders one frame of `scene`. Rays go through pixel centres (integer pixel coordinates, as in
/// the analytic renderer); pixels whose first hit lies beyond `max_depth_m` (z distance) or that
/// hit nothing get depth 0, a zero normal and `Lighting{}.background`. Both sides of a triangle
/// are hit. Per hit pixel:
/// - depth: the ray's intersection with the plane of the triangle Embree found, recomputed in
///   double precision (exact to double rounding for the mesh's float vertices);
/// - normal: the triangle's geometric normal, turned to face the camera;
/// - colour: the vertex colours interpolated with the hit's barycentric coordinates when the
///   mesh has colours (as stored, unshaded); otherwise a 0.7 grey albedo shaded like the
///   analytic renderer with `Lighting{}`: albedo x (ambient + (1 - ambient) max(0, n . to_light)).
/// Rows run in parallel. Throws `Error(InvalidArgument)` for an invalid camera, a non-positive
/// `max_depth_m` or a moved-from scene.
RenderedFrame render(const MeshScene& scene, const PinholeCamera& camera, const Pose& T_wc,
                     double max_depth_m = 10.0);

/// A triangle mesh made ready for ray casting: its own copy of the vertices, colours and
/// triangles, and an acceleration structure built once. Not copyable; movable (a moved-from
/// scene renders nothing and says so). Rendering from several threads at once is safe.
class MeshScene {
 public:
  /// Builds the scene. Throws `Error(InvalidArgument)` for a mesh without triangles, with a
  /// non-finite vertex or an index out of range (naming it), and an `Error` naming Embree's
  /// problem when Embree fails (`Unsupported` for an unsupported CPU, `OutOfCapacity` for memory).
  explicit MeshScene(const TriangleMesh& mesh);
  ~MeshScene();
  MeshScene(MeshScene&& other) noexcept;
  MeshScene& operator=(MeshScene&& other) noexcept;
  MeshScene(const MeshScene&) = delete;
  MeshScene& operator=(const MeshScene&) = delete;

  /// Box around the vertices that triangles use, world frame, mesh units (metres).
  const Aabb& bounds() const;
  int64_t triangle_count() const;
  int64_t vertex_count() const;
  /// Whether the mesh has vertex colours (interpolated into the rendered colour).
  bool has_colors() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  friend RenderedFrame render_mesh(const MeshScene& scene, const PinholeCamera& camera,
                                   const Pose& T_wc, double max_depth_m, MeshRayMode mode);
};

}  // namespace hivox

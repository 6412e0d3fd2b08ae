#include "hivox/synth_mesh/mesh_render.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>
#include <string>
#include <vector>

#include "core/parallel.h"
#include "hivox/core/error.h"
#include "synth_mesh/mesh_render_modes.h"

namespace hivox {

namespace {

std::string_view embree_error_name(RTCError code) {
  switch (code) {
    case RTC_ERROR_NONE:
      return "no error";
    case RTC_ERROR_INVALID_ARGUMENT:
      return "invalid argument";
    case RTC_ERROR_INVALID_OPERATION:
      return "invalid operation";
    case RTC_ERROR_OUT_OF_MEMORY:
      return "out of memory";
    case RTC_ERROR_UNSUPPORTED_CPU:
      return "unsupported CPU";
    case RTC_ERROR_CANCELLED:
      return "cancelled";
    default:
      return "unknown error";
  }
}

ErrorCode error_code_of(RTCError code) {
  switch (code) {
    case RTC_ERROR_OUT_OF_MEMORY:
      return ErrorCode::OutOfCapacity;
    case RTC_ERROR_UNSUPPORTED_CPU:
      return ErrorCode::Unsupported;
    default:
      return ErrorCode::InvalidArgument;
  }
}

uint8_t to_byte(float v) {
  return static_cast<uint8_t>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
}

Eigen::Vector3d to_eigen(const Vec3f& v) {
  return {v.x, v.y, v.z};
}

// The grey of meshes without colours, as the analytic scenes' default material.
constexpr float kGreyAlbedo = 0.7f;

}  // namespace

struct MeshScene::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::vector<Vec3f> positions_w;
  std::vector<Rgb8> colors;
  std::vector<std::array<int32_t, 3>> triangles;
  // Per triangle, its plane n . p = offset with the unit normal of its winding (zero for a
  // degenerate triangle, which Embree never reports hit), in double precision.
  struct Plane {
    Eigen::Vector3d n_w = Eigen::Vector3d::Zero();
    double offset_m = 0;
  };
  std::vector<Plane> planes;
  Aabb bounds_w;
  // Embree reports the text of an error through a callback (possibly from its build threads).
  std::mutex error_mutex;
  std::string error_text;

  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }

  static void on_error(void* user, RTCError code, const char* text) {
    auto* self = static_cast<Impl*>(user);
    const std::lock_guard lock(self->error_mutex);
    if (self->error_text.empty())
      self->error_text =
          fmt::format("{}{}{}", embree_error_name(code), text ? ": " : "", text ? text : "");
  }

  // Throws the device's pending error, if any, saying which step failed.
  void check(std::string_view step) {
    const RTCError code = rtcGetDeviceError(device);
    if (code == RTC_ERROR_NONE) return;
    std::string text;
    {
      const std::lock_guard lock(error_mutex);
      text = error_text.empty() ? std::string(embree_error_name(code)) : error_text;
    }
    fail(error_code_of(code), "mesh scene: Embree could not {} ({})", step, text);
  }
};

MeshScene::MeshScene(const TriangleMesh& mesh) : impl_(std::make_unique<Impl>()) {
  mesh.validate();
  if (mesh.triangles.empty())
    fail(ErrorCode::InvalidArgument, "mesh scene: the mesh has no triangles ({} vertices)",
         mesh.vertex_count());
  for (std::size_t i = 0; i < mesh.positions_w.size(); ++i) {
    const Vec3f& p = mesh.positions_w[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      fail(ErrorCode::InvalidArgument, "mesh scene: vertex {} is not finite ({}, {}, {})", i, p.x,
           p.y, p.z);
  }
  Impl& s = *impl_;
  s.positions_w = mesh.positions_w;
  s.colors = mesh.colors;
  s.triangles = mesh.triangles;
  s.planes.resize(s.triangles.size());
  for (std::size_t i = 0; i < s.triangles.size(); ++i) {
    const auto& t = s.triangles[i];
    const Eigen::Vector3d p0 = to_eigen(s.positions_w[t[0]]);
    const Eigen::Vector3d n =
        (to_eigen(s.positions_w[t[1]]) - p0).cross(to_eigen(s.positions_w[t[2]]) - p0);
    if (n.squaredNorm() > 0.0) s.planes[i] = {n.normalized(), n.normalized().dot(p0)};
    for (const int32_t v : t) s.bounds_w.extend(to_eigen(s.positions_w[v]));
  }

  s.device = rtcNewDevice(nullptr);
  if (!s.device) {
    const RTCError code = rtcGetDeviceError(nullptr);
    fail(error_code_of(code), "mesh scene: Embree could not create a device ({})",
         embree_error_name(code));
  }
  rtcSetDeviceErrorFunction(s.device, &Impl::on_error, &s);

  s.scene = rtcNewScene(s.device);
  s.check("create a scene");
  // Robust: rays through shared edges and vertices never slip between two triangles.
  rtcSetSceneFlags(s.scene, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(s.scene, RTC_BUILD_QUALITY_HIGH);

  RTCGeometry geometry = rtcNewGeometry(s.device, RTC_GEOMETRY_TYPE_TRIANGLE);
  s.check("create a triangle geometry");
  // Embree's own buffers: they carry the padding its vector loads read past the last vertex.
  auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0,
                                                               RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                                               s.positions_w.size()));
  auto* indices = static_cast<uint32_t*>(
      rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                              3 * sizeof(uint32_t), s.triangles.size()));
  if (!vertices || !indices) {
    rtcReleaseGeometry(geometry);
    s.check("allocate the vertex and index buffers");
    fail(ErrorCode::OutOfCapacity, "mesh scene: Embree could not allocate the buffers");
  }
  for (std::size_t i = 0; i < s.positions_w.size(); ++i) {
    vertices[3 * i + 0] = s.positions_w[i].x;
    vertices[3 * i + 1] = s.positions_w[i].y;
    vertices[3 * i + 2] = s.positions_w[i].z;
  }
  for (std::size_t i = 0; i < s.triangles.size(); ++i)
    for (int k = 0; k < 3; ++k) indices[3 * i + k] = static_cast<uint32_t>(s.triangles[i][k]);
  rtcCommitGeometry(geometry);
  rtcAttachGeometry(s.scene, geometry);
  rtcReleaseGeometry(geometry);  // the scene holds it now
  s.check("commit the triangle geometry");
  rtcCommitScene(s.scene);
  s.check("build the scene");
}

MeshScene::~MeshScene() = default;
MeshScene::MeshScene(MeshScene&& other) noexcept = default;
MeshScene& MeshScene::operator=(MeshScene&& other) noexcept = default;

const Aabb& MeshScene::bounds() const {
  static const Aabb kEmpty;
  return impl_ ? impl_->bounds_w : kEmpty;
}
int64_t MeshScene::triangle_count() const {
  return impl_ ? static_cast<int64_t>(impl_->triangles.size()) : 0;
}
int64_t MeshScene::vertex_count() const {
  return impl_ ? static_cast<int64_t>(impl_->positions_w.size()) : 0;
}
bool MeshScene::has_colors() const {
  return impl_ && !impl_->colors.empty();
}

namespace detail {

// What a ray found: the triangle and Embree's barycentric coordinates and distance.
struct RayHit {
  uint32_t triangle = RTC_INVALID_GEOMETRY_ID;  // primID; invalid: no hit
  float bu = 0, bv = 0;                         // hit = (1 - bu - bv) p0 + bu p1 + bv p2
  float t = 0;                                  // Embree's float ray parameter (= depth)
};

}  // namespace detail

RenderedFrame render_mesh(const MeshScene& mesh_scene, const PinholeCamera& camera,
                          const Pose& T_wc, double max_depth_m, MeshRayMode mode) {
  camera.validate("render camera");
  if (!(max_depth_m > 0.0))
    fail(ErrorCode::InvalidArgument, "render: max_depth_m must be > 0, got {}", max_depth_m);
  if (!mesh_scene.impl_)
    fail(ErrorCode::InvalidArgument, "render: the mesh scene was moved from; it holds no mesh");
  const MeshScene::Impl& s = *mesh_scene.impl_;
  const Lighting light;
  RenderedFrame out;
  out.T_wc = T_wc;
  out.depth_m.resize(camera.width, camera.height, 0.0f);
  out.color.resize(camera.width, camera.height, light.background);
  out.normal_w.resize(camera.width, camera.height, Vec3f{});

  const Eigen::Matrix3d R_wc = T_wc.linear();
  const Eigen::Vector3d origin_w = T_wc.translation();
  const float org[3] = {static_cast<float>(origin_w.x()), static_cast<float>(origin_w.y()),
                        static_cast<float>(origin_w.z())};
  const double fx = camera.fx, fy = camera.fy, cx = camera.cx, cy = camera.cy;
  const bool has_colors = !s.colors.empty();
  // Direction with unit z in the camera frame: the ray parameter t is the depth.
  auto ray_dir_w = [&](int u, int v) -> Eigen::Vector3d {
    return R_wc * Eigen::Vector3d((u - cx) / fx, (v - cy) / fy, 1.0);
  };

  // Depth, normal and colour of pixel (u, v) from its ray's hit.
  auto finish = [&](int u, int v, const Eigen::Vector3d& dir_w, const detail::RayHit& hit) {
    if (hit.triangle == RTC_INVALID_GEOMETRY_ID) return;
    // The hit again in double precision: the ray against the plane of the triangle hit.
    const MeshScene::Impl::Plane& plane = s.planes[hit.triangle];
    const double n_dot_dir = plane.n_w.dot(dir_w);
    // Embree's float t where the ray grazes the plane (the plane division loses precision).
    double z = hit.t;
    if (n_dot_dir * n_dot_dir > 1e-12 * dir_w.squaredNorm())
      z = (plane.offset_m - plane.n_w.dot(origin_w)) / n_dot_dir;
    if (!(z > 0.0) || z > max_depth_m) return;
    const Eigen::Vector3d n_w = n_dot_dir > 0.0 ? Eigen::Vector3d(-plane.n_w) : plane.n_w;

    out.depth_m(u, v) = static_cast<float>(z);
    out.normal_w(u, v) = {static_cast<float>(n_w.x()), static_cast<float>(n_w.y()),
                          static_cast<float>(n_w.z())};
    if (has_colors) {
      const float b0 = 1.0f - hit.bu - hit.bv;
      const auto& tri = s.triangles[hit.triangle];
      const Rgb8 &c0 = s.colors[tri[0]], &c1 = s.colors[tri[1]], &c2 = s.colors[tri[2]];
      auto mix = [&](uint8_t a, uint8_t b, uint8_t c) {
        return to_byte((b0 * a + hit.bu * b + hit.bv * c) / 255.0f);
      };
      out.color(u, v) = {mix(c0.r, c1.r, c2.r), mix(c0.g, c1.g, c2.g), mix(c0.b, c1.b, c2.b)};
    } else {
      const uint8_t grey = to_byte(kGreyAlbedo * light.shade(n_w));
      out.color(u, v) = {grey, grey, grey};
    }
  };

  if (mode == MeshRayMode::Single) {
    parallel_for_dynamic(camera.height, 4, [&](int64_t row) {
      const int v = static_cast<int>(row);
      RTCIntersectContext context;
      rtcInitIntersectContext(&context);
      for (int u = 0; u < camera.width; ++u) {
        const Eigen::Vector3d dir_w = ray_dir_w(u, v);
        RTCRayHit rh;
        rh.ray.org_x = org[0];
        rh.ray.org_y = org[1];
        rh.ray.org_z = org[2];
        rh.ray.dir_x = static_cast<float>(dir_w.x());
        rh.ray.dir_y = static_cast<float>(dir_w.y());
        rh.ray.dir_z = static_cast<float>(dir_w.z());
        rh.ray.tnear = 0.0f;
        rh.ray.tfar = static_cast<float>(max_depth_m);
        rh.ray.time = 0.0f;
        rh.ray.mask = std::numeric_limits<unsigned>::max();
        rh.ray.id = 0;
        rh.ray.flags = 0;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(s.scene, &context, &rh);
        finish(u, v, dir_w,
               {rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? RTC_INVALID_GEOMETRY_ID : rh.hit.primID,
                rh.hit.u, rh.hit.v, rh.ray.tfar});
      }
    });
    return out;
  }

  // Packets of 16 neighbouring rays (4 x 4 pixel tiles): they traverse the same nodes, which
  // Embree's packet traversal shares. Each band of 4 rows is one work item.
  constexpr int kTile = 4;
  const int tiles_x = (camera.width + kTile - 1) / kTile;
  const int bands = (camera.height + kTile - 1) / kTile;
  parallel_for_dynamic(bands, 1, [&](int64_t band) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    RTCRayHit16 packet;
    alignas(64) int valid[16];
    Eigen::Vector3d dirs_w[16];
    for (int tx = 0; tx < tiles_x; ++tx) {
      for (int k = 0; k < 16; ++k) {
        const int u = tx * kTile + k % kTile, v = static_cast<int>(band) * kTile + k / kTile;
        valid[k] = (u < camera.width && v < camera.height) ? -1 : 0;
        dirs_w[k] = ray_dir_w(u, v);
        packet.ray.org_x[k] = org[0];
        packet.ray.org_y[k] = org[1];
        packet.ray.org_z[k] = org[2];
        packet.ray.dir_x[k] = static_cast<float>(dirs_w[k].x());
        packet.ray.dir_y[k] = static_cast<float>(dirs_w[k].y());
        packet.ray.dir_z[k] = static_cast<float>(dirs_w[k].z());
        packet.ray.tnear[k] = 0.0f;
        packet.ray.tfar[k] = static_cast<float>(max_depth_m);
        packet.ray.time[k] = 0.0f;
        packet.ray.mask[k] = std::numeric_limits<unsigned>::max();
        packet.ray.id[k] = static_cast<unsigned>(k);
        packet.ray.flags[k] = 0;
        packet.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
        packet.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
      }
      rtcIntersect16(valid, s.scene, &context, &packet);
      for (int k = 0; k < 16; ++k) {
        if (!valid[k]) continue;
        const int u = tx * kTile + k % kTile, v = static_cast<int>(band) * kTile + k / kTile;
        const bool hit = packet.hit.geomID[k] != RTC_INVALID_GEOMETRY_ID;
        finish(u, v, dirs_w[k],
               {hit ? packet.hit.primID[k] : RTC_INVALID_GEOMETRY_ID, packet.hit.u[k],
                packet.hit.v[k], packet.ray.tfar[k]});
      }
    }
  });
  return out;
}

RenderedFrame render(const MeshScene& scene, const PinholeCamera& camera, const Pose& T_wc,
                     double max_depth_m) {
  return render_mesh(scene, camera, T_wc, max_depth_m, MeshRayMode::Packets);
}

}  // namespace hivox

// Developer tool, not a test: fuses the analytic test scenes, extracts their meshes, writes
// them as PLY, renders PNG previews with a tiny software rasteriser, and times extraction on a
// large map. Usage: mesh_preview OUT_DIR
//
// `mesh_preview OUT_DIR MESH.ply EX EY EZ TX TY TZ` renders a mesh file instead, seen from eye
// (EX, EY, EZ) looking at (TX, TY, TZ) with +z up: e.g. a reconstruction, to look for cracks
// where resolution levels meet (`*_levels.png` colours the levels as the raycast level render
// does).
//
// Renders: grey Lambert shading from the geometric (winding) normal; triangles seen from
// behind are drawn red, so wrong orientation or a hole that shows the inside stands out.
// `*_color.png` shows vertex colours, `*_normals.png` the vertex normals as RGB.

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <limits>

#include "analytic_scene.h"
#include "hivox/core/threads.h"
#include "hivox/io/image_io.h"
#include "hivox/io/ply.h"
#include "hivox/mesh/extract_mesh.h"
#include "hivox/raycast/render.h"
#include "mesh/mesh_test_util.h"
#include "mesh/mesh_topology.h"

namespace hivox {
namespace {

enum class Shade { Geometry, Color, Normals, Levels };

ColorImage render(const TriangleMesh& m, const PinholeCamera& cam, const Pose& T_wc, Shade shade) {
  ColorImage img(cam.width, cam.height, Rgb8{40, 40, 60});
  std::vector<float> zbuf(img.size(), std::numeric_limits<float>::infinity());
  const Rigid3f T_cw = to_rigid3f(T_wc.inverse());
  std::vector<Vec3f> p_c(m.positions_w.size());
  for (std::size_t i = 0; i < p_c.size(); ++i) p_c[i] = T_cw * m.positions_w[i];
  for (const auto& t : m.triangles) {
    const Vec3f a = p_c[t[0]], b = p_c[t[1]], c = p_c[t[2]];
    if (a.z < 0.05f || b.z < 0.05f || c.z < 0.05f) continue;
    const Vec3f n = normalized(cross(b - a, c - a));
    const Vec3f view = normalized((a + b + c) / 3.0f);
    const float facing = -dot(n, view);  // > 0: front face
    const Vec2f pa = cam.project(a), pb = cam.project(b), pc = cam.project(c);
    const float area = (pb.x - pa.x) * (pc.y - pa.y) - (pb.y - pa.y) * (pc.x - pa.x);
    if (std::abs(area) < 1e-12f) continue;
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min({pa.x, pb.x, pc.x}))));
    const int x1 =
        std::min(cam.width - 1, static_cast<int>(std::ceil(std::max({pa.x, pb.x, pc.x}))));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min({pa.y, pb.y, pc.y}))));
    const int y1 =
        std::min(cam.height - 1, static_cast<int>(std::ceil(std::max({pa.y, pb.y, pc.y}))));
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const float px = static_cast<float>(x), py = static_cast<float>(y);
        const float w0 = ((pb.x - px) * (pc.y - py) - (pb.y - py) * (pc.x - px)) / area;
        const float w1 = ((pc.x - px) * (pa.y - py) - (pc.y - py) * (pa.x - px)) / area;
        const float w2 = 1.0f - w0 - w1;
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        const float z = w0 * a.z + w1 * b.z + w2 * c.z;
        float& zb = zbuf[static_cast<std::size_t>(y) * cam.width + x];
        if (z >= zb) continue;
        zb = z;
        Rgb8 out;
        if (shade == Shade::Geometry) {
          const float l = 0.15f + 0.85f * std::abs(facing);
          const auto g = static_cast<uint8_t>(255.0f * l);
          out = facing > 0 ? Rgb8{g, g, g} : Rgb8{g, 0, 0};
        } else if (shade == Shade::Color && !m.colors.empty()) {
          const float l = 0.4f + 0.6f * std::abs(facing);
          auto ch = [&](uint8_t Rgb8::*c) {
            return static_cast<uint8_t>(l * (w0 * (m.colors[t[0]].*c) + w1 * (m.colors[t[1]].*c) +
                                             w2 * (m.colors[t[2]].*c)));
          };
          out = {ch(&Rgb8::r), ch(&Rgb8::g), ch(&Rgb8::b)};
        } else if (shade == Shade::Levels && !m.levels.empty()) {
          const float l = 0.3f + 0.7f * std::abs(facing);
          const Rgb8 c = level_color(m.levels[t[0]]);
          out = {static_cast<uint8_t>(l * c.r), static_cast<uint8_t>(l * c.g),
                 static_cast<uint8_t>(l * c.b)};
        } else if (!m.normals_w.empty()) {
          const Vec3f nv =
              normalized(m.normals_w[t[0]] * w0 + m.normals_w[t[1]] * w1 + m.normals_w[t[2]] * w2);
          out = {static_cast<uint8_t>(127.5f * (nv.x + 1)),
                 static_cast<uint8_t>(127.5f * (nv.y + 1)),
                 static_cast<uint8_t>(127.5f * (nv.z + 1))};
        }
        img(x, y) = out;
      }
  }
  return img;
}

void preview(const std::filesystem::path& dir, const std::string& name, const TriangleMesh& m,
             const std::vector<Pose>& views, bool write_mesh = true) {
  if (write_mesh) write_ply(dir / (name + ".ply"), m);
  const PinholeCamera cam{500.0f, 500.0f, 319.5f, 239.5f, 640, 480};
  for (std::size_t i = 0; i < views.size(); ++i) {
    const std::string base = (dir / (name + "_" + std::to_string(i))).string();
    write_png(base + ".png", render(m, cam, views[i], Shade::Geometry));
    if (!m.colors.empty()) write_png(base + "_color.png", render(m, cam, views[i], Shade::Color));
    write_png(base + "_normals.png", render(m, cam, views[i], Shade::Normals));
    if (!m.levels.empty()) write_png(base + "_levels.png", render(m, cam, views[i], Shade::Levels));
  }
  const test::MeshTopology topo = test::mesh_topology(m.vertex_count(), m.triangles);
  std::printf("%s: %lld vertices, %lld triangles, %lld boundary edges\n", name.c_str(),
              static_cast<long long>(m.vertex_count()), static_cast<long long>(m.triangle_count()),
              static_cast<long long>(topo.boundary_edges));
}

/// Fuses the sphere-on-plane scene with a colour checkerboard painted on the world.
std::unique_ptr<VoxelBlockMap> fuse_checkered(const test::SphereOnPlane& scene, float voxel_m) {
  auto map = std::make_unique<VoxelBlockMap>(test::mesh_map_params(voxel_m, 1, true, 4 * voxel_m));
  FusionParams fp;
  fp.depth_range.max_m = 1.5f;
  TsdfIntegrator integrator(fp);
  const PinholeCamera cam = test::small_camera();
  for (const Pose& T_wc : test::orbit(scene.centre, 0.9, 0.5, 16, 0.3)) {
    const DepthImage depth = scene.render(cam, T_wc);
    ColorImage color(cam.width, cam.height);
    for (int y = 0; y < cam.height; ++y)
      for (int x = 0; x < cam.width; ++x) {
        const Eigen::Vector3d p =
            T_wc * Eigen::Vector3d((x - cam.cx) / cam.fx * depth(x, y),
                                   (y - cam.cy) / cam.fy * depth(x, y), depth(x, y));
        const int k = static_cast<int>(std::floor(p.x() / 0.05) + std::floor(p.y() / 0.05) +
                                       std::floor(p.z() / 0.05));
        color(x, y) = (k & 1) ? Rgb8{230, 120, 30} : Rgb8{40, 90, 200};
      }
    FusionInput in{.depth_m = &depth, .color = &color, .rig = CameraRig::registered(cam)};
    in.T_wc = T_wc;
    integrator.fuse(*map, in);
  }
  return map;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void time_large_map() {
  // A wavy 4 m x 4 m surface at 2 mm voxels, written straight from its (approximate) SDF.
  const float voxel = 0.002f;
  MapParams mp = test::mesh_map_params(voxel);
  mp.max_blocks = 1 << 18;
  mp.buckets_per_level = 1 << 18;
  mp.excess_per_level = 1 << 17;
  VoxelBlockMap map(mp);
  const double mu = 4 * voxel;
  const test::Sdf sdf = [](const Eigen::Vector3d& p) {
    return (p.z() - 0.05 * std::sin(p.x() / 0.2) * std::cos(p.y() / 0.3)) / 1.3;
  };
  auto t0 = std::chrono::steady_clock::now();
  test::write_sdf_band(map, 0, {0, 0, -0.08}, {4.0, 4.0, 0.08}, mu, mu, sdf);
  std::printf("large map: %lld blocks written in %.1f s\n",
              static_cast<long long>(map.blocks_in_use()), seconds_since(t0));
  for (const int threads : {1, 2}) {
    set_thread_count(threads);
    extract_mesh(map);  // warm-up: first touch of the output memory
    double best = 1e9;
    TriangleMesh m;
    for (int rep = 0; rep < 3; ++rep) {
      t0 = std::chrono::steady_clock::now();
      m = extract_mesh(map);
      best = std::min(best, seconds_since(t0));
    }
    std::printf(
        "extract_mesh, %d thread(s): %lld blocks -> %lld vertices, %lld triangles in %.3f s\n",
        threads, static_cast<long long>(map.blocks_in_use()),
        static_cast<long long>(m.vertex_count()), static_cast<long long>(m.triangle_count()), best);
  }
  set_thread_count(0);
}

}  // namespace
}  // namespace hivox

int main(int argc, char** argv) {
  using namespace hivox;
  if (argc != 2 && argc != 9) {
    std::fprintf(stderr, "usage: %s OUT_DIR [MESH.ply EX EY EZ TX TY TZ]\n", argv[0]);
    return 2;
  }
  const std::filesystem::path dir = argv[1];
  std::filesystem::create_directories(dir);
  if (argc == 9) {
    const TriangleMesh m = read_ply(argv[2]);
    const Eigen::Vector3d eye(std::atof(argv[3]), std::atof(argv[4]), std::atof(argv[5]));
    const Eigen::Vector3d target(std::atof(argv[6]), std::atof(argv[7]), std::atof(argv[8]));
    preview(dir, std::filesystem::path(argv[2]).stem().string() + "_view", m,
            {look_at(eye, target, Eigen::Vector3d::UnitZ())}, false);
    return 0;
  }
  const test::SphereOnPlane scene;
  const std::vector<Pose> views = {
      look_at({0.7, -0.6, 0.6}, scene.centre, Eigen::Vector3d::UnitZ()),
      look_at({0.0, 0.05, 1.1}, {0, 0, 0.1}, Eigen::Vector3d::UnitY())};
  preview(dir, "sphere_on_plane", extract_mesh(*fuse_checkered(scene, 0.008f)), views);

  test::SphereOnPlane floating;
  floating.with_floor = false;
  const auto map = test::fuse_scene(floating, 0.008f, 0.032f, 12, {0.5, -0.5});
  preview(dir, "floating_sphere", extract_mesh(*map),
          {look_at({0.6, -0.5, 0.45}, floating.centre, Eigen::Vector3d::UnitZ()),
           look_at({0.5, 0.4, -0.4}, floating.centre, Eigen::Vector3d::UnitZ())});
  // The same sphere written straight from its exact SDF: what the mesher does without fusion's
  // quantisation (160x120 pixels are about a voxel wide at this range).
  VoxelBlockMap exact(test::mesh_map_params(0.008f));
  const test::Sdf sdf = [&](const Eigen::Vector3d& p) { return floating.sdf(p); };
  test::write_sdf_band(exact, 0, floating.centre.array() - 0.3, floating.centre.array() + 0.3,
                       0.032, 0.032, sdf);
  preview(dir, "exact_sphere", extract_mesh(exact),
          {look_at({0.6, -0.5, 0.45}, floating.centre, Eigen::Vector3d::UnitZ())});
  time_large_map();
  return 0;
}

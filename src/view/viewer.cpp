#include "hivox/view/viewer.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <unordered_map>

#include <nlohmann/json.hpp>

#include "hivox/core/error.h"
#include "hivox/io/map_file.h"
#include "hivox/io/mesh_file.h"
#include "hivox/io/ply.h"
#include "hivox/io/trajectory_io.h"
#include "hivox/mesh/extract_mesh.h"
#include "hivox/raycast/render.h"
#include "view/assets.h"
#include "view/json_util.h"

namespace hivox {

namespace fs = std::filesystem;
using json = nlohmann::json;

void ViewerParams::validate() const {
  if (max_triangles < 1000)
    fail(ErrorCode::InvalidArgument, "viewer max triangles must be >= 1000, got {}", max_triangles);
  if (!(min_weight >= 1.0f))
    fail(ErrorCode::InvalidArgument, "viewer min weight must be >= 1, got {}", min_weight);
}

namespace {

std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(ErrorCode::Io, "{}: cannot read", path.string());
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// Sum of triangle areas, square metres.
double surface_area(const TriangleMesh& mesh) {
  double area = 0;
  for (const auto& t : mesh.triangles) {
    const Vec3f a = mesh.positions_w[t[0]], b = mesh.positions_w[t[1]], c = mesh.positions_w[t[2]];
    area += 0.5 * static_cast<double>(norm(cross(b - a, c - a)));
  }
  return area;
}

TriangleMesh cluster_vertices(const TriangleMesh& mesh, double cell_m) {
  const bool normals = !mesh.normals_w.empty(), colors = !mesh.colors.empty(),
             levels = !mesh.levels.empty();
  std::unordered_map<uint64_t, int32_t> cells;
  cells.reserve(mesh.positions_w.size() / 4);
  std::vector<int32_t> remap(mesh.positions_w.size());
  std::vector<Vec3f> sum_p, sum_n;
  std::vector<std::array<uint32_t, 3>> sum_c;
  std::vector<uint32_t> count;
  std::vector<uint8_t> level;
  const double inv = 1.0 / cell_m;
  for (std::size_t v = 0; v < mesh.positions_w.size(); ++v) {
    const Vec3f& p = mesh.positions_w[v];
    auto key_of = [&](float x) {
      return static_cast<uint64_t>(static_cast<int64_t>(std::floor(x * inv)) + (1 << 20)) &
             0x1fffff;
    };
    const uint64_t key = key_of(p.x) | key_of(p.y) << 21 | key_of(p.z) << 42;
    const auto [it, added] = cells.try_emplace(key, static_cast<int32_t>(sum_p.size()));
    const int32_t c = it->second;
    if (added) {
      sum_p.push_back({});
      sum_n.push_back({});
      sum_c.push_back({0, 0, 0});
      count.push_back(0);
      level.push_back(levels ? mesh.levels[v] : 0);
    }
    remap[v] = c;
    sum_p[c] = sum_p[c] + p;
    if (normals) sum_n[c] = sum_n[c] + mesh.normals_w[v];
    if (colors) {
      sum_c[c][0] += mesh.colors[v].r;
      sum_c[c][1] += mesh.colors[v].g;
      sum_c[c][2] += mesh.colors[v].b;
    }
    if (levels) level[c] = std::min(level[c], mesh.levels[v]);
    ++count[c];
  }
  TriangleMesh out;
  const std::size_t n = sum_p.size();
  out.positions_w.resize(n);
  if (normals) out.normals_w.resize(n);
  if (colors) out.colors.resize(n);
  if (levels) out.levels = level;
  for (std::size_t c = 0; c < n; ++c) {
    const float k = 1.0f / static_cast<float>(count[c]);
    out.positions_w[c] = sum_p[c] * k;
    if (normals) {
      const float len = norm(sum_n[c]);
      out.normals_w[c] = len > 0 ? sum_n[c] * (1.0f / len) : Vec3f{0, 0, 1};
    }
    if (colors)
      out.colors[c] = {static_cast<uint8_t>(sum_c[c][0] / count[c]),
                       static_cast<uint8_t>(sum_c[c][1] / count[c]),
                       static_cast<uint8_t>(sum_c[c][2] / count[c])};
  }
  for (const auto& t : mesh.triangles) {
    const std::array<int32_t, 3> r = {remap[t[0]], remap[t[1]], remap[t[2]]};
    if (r[0] != r[1] && r[1] != r[2] && r[0] != r[2]) out.triangles.push_back(r);
  }
  return out;
}

template <typename T>
void append(std::string& out, const T* data, std::size_t count) {
  out.append(reinterpret_cast<const char*>(data), count * sizeof(T));
  out.resize((out.size() + 3) / 4 * 4, '\0');
}

Eigen::Vector3d to_vector(const Vec3f& v) {
  return {v.x, v.y, v.z};
}

/// Where the page's camera starts: looking at the mesh's centre along the cameras' mean viewing
/// direction (image "up" as up), from behind and a little above, far enough to see it whole;
/// without poses from a corner above, +y up.
struct HomeView {
  Eigen::Vector3d eye, target, up;
};
HomeView home_view(const ViewerContent& c, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  HomeView h;
  h.target = 0.5 * (lo + hi);
  const double radius = std::max(0.5 * (hi - lo).norm(), 0.05);
  Eigen::Vector3d forward(0, 0, 0), up(0, 0, 0);
  for (const Pose& p : c.trajectory) {
    forward += p.rotation() * Eigen::Vector3d::UnitZ();
    up -= p.rotation() * Eigen::Vector3d::UnitY();
  }
  if (forward.norm() < 1e-6 || up.norm() < 1e-6) {
    forward = Eigen::Vector3d(-0.4, -0.5, -1.0);
    up = Eigen::Vector3d::UnitY();
  }
  forward.normalize();
  up = (up - up.dot(forward) * forward);
  up = up.norm() > 1e-6 ? up.normalized() : Eigen::Vector3d::UnitY();
  h.up = up;
  h.eye = h.target - forward * (1.7 * radius) + up * (0.5 * radius);
  return h;
}

}  // namespace

TriangleMesh decimate_for_display(const TriangleMesh& mesh, int64_t max_triangles) {
  if (mesh.triangle_count() <= max_triangles) return mesh;
  // A regular mesh has about two triangles per grid cell on the surface; reconstructed meshes
  // fold and overlap, so start finer than that and coarsen until the mesh fits.
  double cell_m = 0.6 * std::sqrt(2.0 * surface_area(mesh) / static_cast<double>(max_triangles));
  if (!(cell_m > 0)) cell_m = 1e-3;
  for (;;) {
    TriangleMesh out = cluster_vertices(mesh, cell_m);
    if (out.triangle_count() <= max_triangles) return out;
    cell_m *= 1.15;
  }
}

std::string mesh_to_binary(const TriangleMesh& mesh) {
  mesh.validate();
  const bool normals = !mesh.normals_w.empty(), colors = !mesh.colors.empty(),
             levels = !mesh.levels.empty();
  const uint32_t header[4] = {static_cast<uint32_t>(mesh.vertex_count()),
                              static_cast<uint32_t>(mesh.triangle_count()),
                              (normals ? 1u : 0u) | (colors ? 2u : 0u) | (levels ? 4u : 0u), 0u};
  std::string out = "HVXMESH1";
  const std::size_t v = mesh.positions_w.size();
  out.reserve(8 + sizeof header + v * (normals ? 24 : 12) + v * 4 + mesh.triangles.size() * 12);
  append(out, header, 4);
  static_assert(sizeof(Vec3f) == 12 && sizeof(Rgb8) == 3);
  append(out, mesh.positions_w.data(), v);
  if (normals) append(out, mesh.normals_w.data(), v);
  if (colors) append(out, mesh.colors.data(), v);
  if (levels) append(out, mesh.levels.data(), v);
  append(out, mesh.triangles.data(), mesh.triangles.size());
  return out;
}

ViewerContent load_viewer_content(const fs::path& path, const ViewerParams& params) {
  params.validate();
  ViewerContent c;
  c.path = path;
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    c.kind = ViewerContent::Kind::RunFolder;
    c.folder = path;
    const fs::path mesh = path / "mesh.ply";
    if (!fs::exists(mesh, ec))
      fail(ErrorCode::Io, "{}: no mesh.ply in this folder (expected a hivox run's output folder)",
           path.string());
    c.mesh = read_ply(mesh);
    if (fs::exists(path / "trajectory.txt", ec))
      for (const StampedPose& p : read_tum_trajectory(path / "trajectory.txt"))
        c.trajectory.push_back(p.T_wc);
    if (fs::exists(path / "stats.json", ec)) {
      c.stats_json = read_text(path / "stats.json");
      const json stats = json::parse(c.stats_json, nullptr, false);
      if (stats.is_discarded())
        fail(ErrorCode::InvalidData, "{}: not valid JSON", (path / "stats.json").string());
      c.levels = stats.value("levels", 0);
      c.voxel_size_m = stats.value("voxel_size_m", 0.0f);
    }
    for (const auto& entry : fs::directory_iterator(path, ec))
      if (entry.is_regular_file() && entry.path().extension() == ".png")
        c.images.push_back(entry.path().filename().string());
    std::sort(c.images.begin(), c.images.end());
  } else if (!fs::exists(path, ec)) {
    fail(ErrorCode::Io, "{}: no such file or folder", path.string());
  } else if (is_map_file(path)) {
    c.kind = ViewerContent::Kind::MapFile;
    const LoadedMap loaded = read_map_file(path);
    MeshParams mp;
    mp.min_weight = params.min_weight;
    c.mesh = extract_mesh(*loaded.map, mp);
    c.levels = loaded.info.map.levels;
    c.voxel_size_m = loaded.info.map.voxel_size_m;
    if (loaded.info.session.last_pose) c.trajectory.push_back(*loaded.info.session.last_pose);
  } else {
    c.kind = ViewerContent::Kind::MeshFile;
    try {
      c.mesh = read_mesh(path);
    } catch (const Error& e) {
      if (e.code() != ErrorCode::Unsupported) throw;
      fail(ErrorCode::Unsupported,
           "{}; the viewer also takes a run's output folder or a map (.hvx)", e.what());
    }
  }
  if (c.mesh.triangles.empty())
    fail(ErrorCode::InvalidData, "{}: nothing to show: the mesh has no triangles", path.string());
  if (c.levels == 0 && !c.mesh.levels.empty())
    c.levels = 1 + *std::max_element(c.mesh.levels.begin(), c.mesh.levels.end());
  c.source_vertices = c.mesh.vertex_count();
  c.source_triangles = c.mesh.triangle_count();
  c.mesh = decimate_for_display(c.mesh, params.max_triangles);
  return c;
}

void serve_viewer(ViewServer& server, std::shared_ptr<const ViewerContent> content) {
  const std::string info = [&] {
    const ViewerContent& c = *content;
    json j;
    j["path"] = c.path.string();
    j["kind"] = c.kind == ViewerContent::Kind::RunFolder ? "run folder"
                : c.kind == ViewerContent::Kind::MapFile ? "map file"
                                                         : "mesh file";
    j["vertices"] = c.mesh.vertex_count();
    j["triangles"] = c.mesh.triangle_count();
    j["source_vertices"] = c.source_vertices;
    j["source_triangles"] = c.source_triangles;
    j["has_normals"] = !c.mesh.normals_w.empty();
    j["has_colors"] = !c.mesh.colors.empty();
    j["has_levels"] = !c.mesh.levels.empty();
    j["levels"] = c.levels;
    json sizes = json::array(), colors = json::array(), counts = json::array();
    std::vector<int64_t> per_level(static_cast<std::size_t>(std::max(c.levels, 0)), 0);
    for (uint8_t l : c.mesh.levels)
      if (l < per_level.size()) ++per_level[l];
    for (int l = 0; l < c.levels; ++l) {
      sizes.push_back(c.voxel_size_m > 0 ? c.voxel_size_m * static_cast<float>(1 << l) * 1e3f
                                         : 0.0f);
      colors.push_back(view::hex_color(level_color(l)));
      counts.push_back(per_level[static_cast<std::size_t>(l)]);
    }
    j["voxel_sizes_mm"] = sizes;
    j["level_colors"] = colors;
    j["vertices_per_level"] = counts;
    Vec3f lo{INFINITY, INFINITY, INFINITY}, hi{-INFINITY, -INFINITY, -INFINITY};
    for (const Vec3f& p : c.mesh.positions_w)
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], p[a]);
        hi[a] = std::max(hi[a], p[a]);
      }
    if (!c.mesh.empty()) j["bounds_m"] = {{lo.x, lo.y, lo.z}, {hi.x, hi.y, hi.z}};
    const HomeView home = home_view(c, c.mesh.empty() ? Eigen::Vector3d::Zero() : to_vector(lo),
                                    c.mesh.empty() ? Eigen::Vector3d::Ones() : to_vector(hi));
    j["home"] = {{"eye", {home.eye.x(), home.eye.y(), home.eye.z()}},
                 {"target", {home.target.x(), home.target.y(), home.target.z()}},
                 {"up", {home.up.x(), home.up.y(), home.up.z()}},
                 {"distance", (home.eye - home.target).norm()}};
    j["trajectory_poses"] = c.trajectory.size();
    j["images"] = c.images;
    j["stats"] = c.stats_json.empty() ? json() : json::parse(c.stats_json, nullptr, false);
    if (j["stats"].is_object()) j["stats"].erase("per_frame");  // the page needs the summary
    return j.dump();
  }();
  auto mesh = std::make_shared<const std::string>(mesh_to_binary(content->mesh));
  json trajectory = json::array();
  for (const Pose& p : content->trajectory) {
    const Eigen::Vector3d t = p.translation();
    trajectory.push_back({t.x(), t.y(), t.z()});
  }
  const std::string trajectory_text = trajectory.dump();
  server.route("/", [](const HttpQuery&) {
    return HttpReply{200, "text/html; charset=utf-8",
                     std::string(*view::static_asset("viewer.html"))};
  });
  server.route("/api/info.json", [info](const HttpQuery&) { return HttpReply::json(info); });
  server.route("/api/trajectory.json",
               [trajectory_text](const HttpQuery&) { return HttpReply::json(trajectory_text); });
  server.route("/api/mesh.bin", [mesh](const HttpQuery&) {
    return HttpReply{200, "application/octet-stream", *mesh};
  });
  if (!content->folder.empty()) server.serve_folder("/files/", content->folder);
}

}  // namespace hivox

#pragma once
// Maps for mesh tests: written directly from an exact signed distance function, or fused from
// depth images of the analytic scene; and how two meshes differ.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <memory>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "analytic_scene.h"
#include "hivox/fusion/integrator.h"
#include "hivox/map/voxel_block_map.h"
#include "hivox/mesh/params.h"
#include "hivox/mesh/triangle_mesh.h"
#include "map/map_access.h"
#include "map/sample_kernels.h"

namespace hivox::test {

inline MapParams mesh_map_params(float voxel_m, int levels = 1, bool color = true,
                                 float mu_m = MapParams{}.truncation_m) {
  MapParams p;
  p.voxel_size_m = voxel_m;
  p.truncation_m = mu_m;
  p.levels = levels;
  p.max_blocks = 1 << 17;
  p.buckets_per_level = 1 << 16;
  p.excess_per_level = 1 << 15;
  p.store_color = color;
  return p;
}

using Sdf = std::function<double(const Eigen::Vector3d&)>;

/// Writes F = clamp(sdf / mu) with weight `weight` into every voxel of block `b`.
inline void write_sdf_voxels(VoxelBlockMap& map, const BlockRef& b, double mu_m, const Sdf& sdf,
                             uint16_t weight = 1) {
  const double s = map.params().voxel_size_at(b.level);
  TsdfVoxel* vox = MapAccess::tsdf(map, b.ptr);
  for (int i = 0; i < kBlockVoxels; ++i) {
    const Vec3i c = voxel_coords(i);
    const Eigen::Vector3d p(b.pos.x * 8 + c.x, b.pos.y * 8 + c.y, b.pos.z * 8 + c.z);
    vox[i].tsdf = tsdf_from_float(static_cast<float>(sdf(p * s) / mu_m));
    vox[i].weight = weight;
  }
  MapAccess::refresh_surface(map, b.ptr);
}

/// Writes F = clamp(sdf / mu) with weight `weight` into every voxel of the level-`level`
/// blocks in [lo, hi] (block coordinates) that `keep(block)` accepts.
inline void write_sdf_blocks(VoxelBlockMap& map, int level, const Vec3i& lo, const Vec3i& hi,
                             double mu_m, const Sdf& sdf, uint16_t weight = 1,
                             const std::function<bool(const Vec3i&)>& keep = {}) {
  std::vector<BlockKey> keys;
  for (int z = lo.z; z <= hi.z; ++z)
    for (int y = lo.y; y <= hi.y; ++y)
      for (int x = lo.x; x <= hi.x; ++x)
        if (!keep || keep({x, y, z})) keys.push_back({{x, y, z}, level});
  std::vector<BlockRef> inserted;
  map.insert_blocks(keys, &inserted);
  for (const BlockRef& b : inserted) write_sdf_voxels(map, b, mu_m, sdf, weight);
}

/// Writes `sdf` into every block within `band_m` (plus the block's half diagonal) of its zero
/// set inside the box [lo_m, hi_m].
inline void write_sdf_band(VoxelBlockMap& map, int level, const Eigen::Vector3d& lo_m,
                           const Eigen::Vector3d& hi_m, double mu_m, double band_m,
                           const Sdf& sdf) {
  const double block = map.params().block_size_at(level);
  const double half_diag = std::sqrt(3.0) * block / 2;
  auto to_block = [&](double v) { return static_cast<int>(std::floor(v / block)); };
  write_sdf_blocks(map, level, {to_block(lo_m.x()), to_block(lo_m.y()), to_block(lo_m.z())},
                   {to_block(hi_m.x()), to_block(hi_m.y()), to_block(hi_m.z())}, mu_m, sdf, 1,
                   [&](const Vec3i& b) {
                     const Eigen::Vector3d centre =
                         (Eigen::Vector3d(b.x, b.y, b.z) + Eigen::Vector3d::Constant(0.5)) * block;
                     return std::abs(sdf(centre)) < band_m + half_diag;
                   });
}

inline PinholeCamera small_camera() {
  return {160.0f, 160.0f, 79.5f, 59.5f, 160, 120};
}

/// Fuses noise-free renders of `scene` from orbits around it (one per entry of `heights_m`,
/// `views` poses each, 0.9 m from the centre) into `map` (with its truncation band). With
/// `color`, every frame carries a constant colour image. Depth beyond `max_depth_m` is ignored:
/// the floor far away is seen at grazing angles with pixels larger than a voxel.
inline void fuse_views(VoxelBlockMap& map, const SphereOnPlane& scene, int views,
                       const std::vector<double>& heights_m, const Rgb8* color = nullptr,
                       float max_depth_m = 1.5f) {
  FusionParams fp;
  fp.depth_range.max_m = max_depth_m;
  TsdfIntegrator integrator(fp);
  const PinholeCamera cam = small_camera();
  const ColorImage image(cam.width, cam.height, color ? *color : Rgb8{});
  for (const double h : heights_m)
    for (const Pose& T_wc : orbit(scene.centre, 0.9, h, views, 0.3)) {
      const DepthImage depth = scene.render(cam, T_wc);
      FusionInput in;
      in.depth_m = &depth;
      in.rig = CameraRig::registered(cam);
      if (color) in.color = &image;
      in.T_wc = T_wc;
      integrator.fuse(map, in);
    }
}

/// fuse_views into a fresh fixed-grid map with truncation band `mu_m`.
inline std::unique_ptr<VoxelBlockMap> fuse_scene(const SphereOnPlane& scene, float voxel_m,
                                                 float mu_m, int views,
                                                 const std::vector<double>& heights_m,
                                                 const Rgb8* color = nullptr,
                                                 float max_depth_m = 1.5f) {
  auto map = std::make_unique<VoxelBlockMap>(mesh_map_params(voxel_m, 1, true, mu_m));
  fuse_views(*map, scene, views, heights_m, color, max_depth_m);
  return map;
}

/// Mesh settings that change what each pass of the mesher makes, named for traces.
inline std::vector<std::pair<const char*, MeshParams>> mesh_param_cases() {
  std::vector<std::pair<const char*, MeshParams>> cases(4);
  cases[0].first = "defaults";
  cases[1].first = "no normals, no colour";
  cases[1].second.compute_normals = false;
  cases[1].second.with_color = false;
  cases[2].first = "normals, no colour";
  cases[2].second.with_color = false;
  cases[3].first = "min_weight 3, small pieces removed";
  cases[3].second.min_weight = 3;
  cases[3].second.min_piece_triangles = 50;
  return cases;
}

/// How many of two meshes' vertices and triangles differ, index for index (the meshes have the
/// same counts): positions more than 1 micrometre apart, normals more than ~0.8 degrees apart,
/// colours more than 1 apart in a channel, levels, triangles.
struct MeshDifferences {
  int64_t positions = 0, normals = 0, colors = 0, levels = 0, triangles = 0;
  float farthest_m = 0.0f;   ///< the largest distance between two vertices of the same index
  int64_t first_apart = -1;  ///< the first index whose positions differ, or -1
};
inline MeshDifferences mesh_differences(const TriangleMesh& a, const TriangleMesh& b) {
  MeshDifferences d;
  for (std::size_t v = 0; v < a.positions_w.size() && v < b.positions_w.size(); ++v) {
    const float apart = norm(a.positions_w[v] - b.positions_w[v]);
    d.farthest_m = std::max(d.farthest_m, apart);
    if (apart > 1e-6f && d.positions++ == 0) d.first_apart = static_cast<int64_t>(v);
    if (v < a.normals_w.size() && v < b.normals_w.size())
      d.normals += dot(a.normals_w[v], b.normals_w[v]) < 0.9999f;
    if (v < a.colors.size() && v < b.colors.size())
      d.colors += std::abs(a.colors[v].r - b.colors[v].r) > 1 ||
                  std::abs(a.colors[v].g - b.colors[v].g) > 1 ||
                  std::abs(a.colors[v].b - b.colors[v].b) > 1;
    if (v < a.levels.size() && v < b.levels.size()) d.levels += a.levels[v] != b.levels[v];
  }
  for (std::size_t t = 0; t < a.triangles.size() && t < b.triangles.size(); ++t)
    d.triangles += a.triangles[t] != b.triangles[t];
  return d;
}

/// Where two meshes of one map differ, for a failure's message: the counts, the first vertex
/// index whose positions differ (both positions, their levels), and the vertices of each that
/// the other lacks at exactly that position (how many, the first three with their levels):
/// a vertex order that differs shows as the first without the second.
inline std::string describe_mesh_difference(const TriangleMesh& a, const TriangleMesh& b) {
  auto point = [](const Vec3f& p) {
    char s[64];
    std::snprintf(s, sizeof s, "(%.6f %.6f %.6f)", p.x, p.y, p.z);
    return std::string(s);
  };
  auto level = [](const TriangleMesh& m, std::size_t v) {
    return v < m.levels.size() ? std::to_string(m.levels[v]) : std::string("?");
  };
  std::string out = std::to_string(a.vertex_count()) + " / " + std::to_string(b.vertex_count()) +
                    " vertices, " + std::to_string(a.triangle_count()) + " / " +
                    std::to_string(b.triangle_count()) + " triangles";
  if (const int64_t first = mesh_differences(a, b).first_apart; first >= 0) {
    const auto v = static_cast<std::size_t>(first);
    out += "; first vertex apart: " + std::to_string(v) + " " + point(a.positions_w[v]) +
           " level " + level(a, v) + " / " + point(b.positions_w[v]) + " level " + level(b, v);
  }
  auto less = [](const Vec3f& p, const Vec3f& q) {
    return std::tie(p.x, p.y, p.z) < std::tie(q.x, q.y, q.z);
  };
  auto sorted = [&](const TriangleMesh& m) {
    std::vector<std::size_t> order(m.positions_w.size());
    for (std::size_t v = 0; v < order.size(); ++v) order[v] = v;
    std::sort(order.begin(), order.end(), [&](std::size_t i, std::size_t j) {
      return less(m.positions_w[i], m.positions_w[j]);
    });
    return order;
  };
  const std::vector<std::size_t> sa = sorted(a), sb = sorted(b);
  std::vector<std::size_t> only_a, only_b;
  std::size_t i = 0, j = 0;
  while (i < sa.size() || j < sb.size()) {
    if (j == sb.size() || (i < sa.size() && less(a.positions_w[sa[i]], b.positions_w[sb[j]]))) {
      only_a.push_back(sa[i++]);
    } else if (i == sa.size() || less(b.positions_w[sb[j]], a.positions_w[sa[i]])) {
      only_b.push_back(sb[j++]);
    } else {
      ++i;
      ++j;
    }
  }
  auto list = [&](const TriangleMesh& m, const std::vector<std::size_t>& only, const char* name) {
    std::string s = "; " + std::to_string(only.size()) + " only in " + name;
    for (std::size_t k = 0; k < only.size() && k < 3; ++k)
      s += (k == 0 ? ": " : ", ") + std::string("#") + std::to_string(only[k]) + " " +
           point(m.positions_w[only[k]]) + " level " + level(m, only[k]);
    return s;
  };
  return out + list(a, only_a, "the first") + list(b, only_b, "the second");
}

/// What `map` holds where vertex `p` of level `level` was made: its edge (the lattice points of
/// the level below and above it along the axis where it is off the lattice), and at both ends
/// the voxel there (TSDF, weight) of the level or, where its block is split, of a finer one, and
/// the value each coarser level gives there on its own lattice
/// (what a mesher samples at a level boundary). For telling which of two meshers made a vertex from
/// the map's values.
inline std::string describe_vertex_in_map(const VoxelBlockMap& map, const Vec3f& p, int level) {
  const MapView view = map.view();
  if (level < 0 || level >= view.levels) return "level " + std::to_string(level) + " not in map";
  const float voxel_m = view.level[level].voxel_size_m;
  const Vec3f q{p.x / voxel_m, p.y / voxel_m, p.z / voxel_m};
  // The edge's axis: where the vertex is farthest from the lattice.
  int axis = 0;
  for (int a = 1; a < 3; ++a)
    if (std::abs(q[a] - std::round(q[a])) > std::abs(q[axis] - std::round(q[axis]))) axis = a;
  Vec3i g{static_cast<int>(std::lround(q.x)), static_cast<int>(std::lround(q.y)),
          static_cast<int>(std::lround(q.z))};
  g[axis] = static_cast<int>(std::floor(q[axis]));
  char s[160];
  std::snprintf(s, sizeof s, "edge (%d %d %d)+%c at level %d, t %.6f:", g.x, g.y, g.z, "xyz"[axis],
                level, static_cast<double>(q[axis] - static_cast<float>(g[axis])));
  std::string out = s;
  const auto cache = std::make_unique<kernels::BlockLookupCache>();
  cache->reset();
  for (int end = 0; end < 2; ++end) {
    Vec3i v = g;
    v[axis] += end;
    out += end == 0 ? " [" : "; [";
    // The voxel at the point: the level's own, or a finer one where its block is split.
    int32_t ptr = -1;
    Vec3i voxel;
    const int at = kernels::voxel_at_or_finer(view, *cache, level, v, &ptr, &voxel);
    if (at >= 0) {
      const TsdfVoxel t = view.tsdf[int64_t{ptr} * kBlockVoxels + local_voxel_index(voxel)];
      std::snprintf(s, sizeof s, "level %d voxel %.7g w %d", at,
                    static_cast<double>(tsdf_to_float(t.tsdf)), static_cast<int>(t.weight));
    } else {
      std::snprintf(s, sizeof s, "no voxel at level %d or finer", level);
    }
    out += s;
    for (int l = level + 1; l < view.levels; ++l) {
      float f = 0.0f;
      int32_t nearest_ptr = -1;
      int nearest_index = -1;
      if (kernels::sample_on_coarser_lattice(view, *cache, level, v, l, 1.0f, &f, &nearest_ptr,
                                             &nearest_index)) {
        std::snprintf(s, sizeof s, ", level %d lattice %.7g", l, static_cast<double>(f));
        out += s;
      }
    }
    out += "]";
  }
  return out;
}

/// describe_vertex_in_map for the first vertex whose position differs between `a` and `b` (by
/// index), each as its mesh made it.
inline std::string describe_first_difference_in_map(const TriangleMesh& a, const TriangleMesh& b,
                                                    const VoxelBlockMap& map) {
  const int64_t first = mesh_differences(a, b).first_apart;
  const auto v = static_cast<std::size_t>(first);
  if (first < 0 || v >= a.levels.size() || v >= b.levels.size()) return {};
  return "\nvertex " + std::to_string(v) +
         " in the first: " + describe_vertex_in_map(map, a.positions_w[v], a.levels[v]) +
         "\nin the second: " + describe_vertex_in_map(map, b.positions_w[v], b.levels[v]);
}

inline Eigen::Vector3d to_eigen(const Vec3f& v) {
  return {v.x, v.y, v.z};
}

/// Gradient of an SDF by central differences.
inline Eigen::Vector3d sdf_gradient(const Sdf& sdf, const Eigen::Vector3d& p, double h = 1e-5) {
  Eigen::Vector3d g;
  for (int k = 0; k < 3; ++k) {
    Eigen::Vector3d d = Eigen::Vector3d::Zero();
    d[k] = h;
    g[k] = (sdf(p + d) - sdf(p - d)) / (2 * h);
  }
  return g;
}

}  // namespace hivox::test

#include "hivox/mesh/triangle_mesh.h"

#include <cmath>
#include <numeric>
#include <unordered_map>

#include "hivox/core/error.h"

namespace hivox {

namespace {
template <typename T>
void check_attribute(const std::vector<T>& a, std::size_t vertices, const char* name) {
  if (!a.empty() && a.size() != vertices)
    fail(ErrorCode::InvalidArgument, "mesh: {} has {} entries for {} vertices (must be 0 or {})",
         name, a.size(), vertices, vertices);
}
}  // namespace

void TriangleMesh::validate() const {
  const std::size_t n = positions_w.size();
  check_attribute(normals_w, n, "normals_w");
  check_attribute(colors, n, "colors");
  check_attribute(levels, n, "levels");
  for (std::size_t t = 0; t < triangles.size(); ++t)
    for (const int32_t i : triangles[t])
      if (i < 0 || static_cast<std::size_t>(i) >= n)
        fail(ErrorCode::InvalidArgument, "mesh: triangles[{}] has vertex index {} outside [0, {})",
             t, i, n);
}

void TriangleMesh::validate_for_writing(const std::string& path) const {
  try {
    validate();
  } catch (const Error& e) {
    fail(ErrorCode::InvalidArgument, "{}: cannot write: {}", path, e.what());
  }
}

void Box3f::validate(const char* what) const {
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(min_m[a]) || !std::isfinite(max_m[a]) || min_m[a] > max_m[a])
      fail(ErrorCode::InvalidArgument,
           "{} [{}, {}, {}] .. [{}, {}, {}] m: needs finite corners, min <= max on every axis",
           what, min_m.x, min_m.y, min_m.z, max_m.x, max_m.y, max_m.z);
}

namespace {

/// The triangles of `mesh` that `keep` selects, with the vertices they use, in order.
template <typename Keep>
TriangleMesh select_triangles(const TriangleMesh& mesh, Keep keep) {
  std::vector<int32_t> new_index(mesh.positions_w.size(), -1);
  TriangleMesh out;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    if (!keep(t)) continue;
    std::array<int32_t, 3> tri{};
    for (int c = 0; c < 3; ++c) {
      const auto v = static_cast<std::size_t>(mesh.triangles[t][static_cast<std::size_t>(c)]);
      if (new_index[v] < 0) {
        new_index[v] = static_cast<int32_t>(out.positions_w.size());
        out.positions_w.push_back(mesh.positions_w[v]);
        if (!mesh.normals_w.empty()) out.normals_w.push_back(mesh.normals_w[v]);
        if (!mesh.colors.empty()) out.colors.push_back(mesh.colors[v]);
        if (!mesh.levels.empty()) out.levels.push_back(mesh.levels[v]);
      }
      tri[static_cast<std::size_t>(c)] = new_index[v];
    }
    out.triangles.push_back(tri);
  }
  return out;
}

int32_t find_root(std::vector<int32_t>& parent, int32_t i) {
  while (parent[static_cast<std::size_t>(i)] != i) {
    parent[static_cast<std::size_t>(i)] =
        parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(i)])];
    i = parent[static_cast<std::size_t>(i)];
  }
  return i;
}

void join(std::vector<int32_t>& parent, int32_t a, int32_t b) {
  a = find_root(parent, a);
  b = find_root(parent, b);
  if (a != b) parent[static_cast<std::size_t>(std::max(a, b))] = std::min(a, b);
}

}  // namespace

TriangleMesh crop_mesh(const TriangleMesh& mesh, const Box3f& box) {
  return select_triangles(mesh, [&](std::size_t t) {
    for (const int32_t v : mesh.triangles[t])
      if (!box.contains(mesh.positions_w[static_cast<std::size_t>(v)])) return false;
    return true;
  });
}

TriangleMesh remove_small_pieces(const TriangleMesh& mesh, int64_t min_triangles,
                                 float join_distance_m, int64_t* removed_pieces) {
  if (!(join_distance_m > 0.0f) || !std::isfinite(join_distance_m))
    fail(ErrorCode::InvalidArgument, "join distance must be > 0 m, got {}", join_distance_m);
  const auto n = static_cast<int32_t>(mesh.positions_w.size());
  std::vector<int32_t> parent(static_cast<std::size_t>(n));
  std::iota(parent.begin(), parent.end(), 0);
  for (const auto& t : mesh.triangles) {
    join(parent, t[0], t[1]);
    join(parent, t[0], t[2]);
  }
  // Vertices in one grid cell belong together (pieces meeting across a level boundary).
  const float inv = 1.0f / join_distance_m;
  std::unordered_map<uint64_t, int32_t> first_in_cell;
  first_in_cell.reserve(static_cast<std::size_t>(n));
  for (int32_t v = 0; v < n; ++v) {
    const Vec3f& p = mesh.positions_w[static_cast<std::size_t>(v)];
    uint64_t key = 0;  // 21 bits per axis: cells are told apart within 2^21 of each other
    for (int a = 0; a < 3; ++a)
      key |= (static_cast<uint64_t>(static_cast<int64_t>(std::floor(p[a] * inv))) & 0x1fffffu)
             << (21 * a);
    const auto [it, fresh] = first_in_cell.emplace(key, v);
    if (!fresh) join(parent, it->second, v);
  }
  std::vector<int64_t> size(static_cast<std::size_t>(n), 0);
  for (const auto& t : mesh.triangles) ++size[static_cast<std::size_t>(find_root(parent, t[0]))];
  int64_t removed = 0;
  for (int32_t v = 0; v < n; ++v)
    if (find_root(parent, v) == v && size[static_cast<std::size_t>(v)] > 0 &&
        size[static_cast<std::size_t>(v)] < min_triangles)
      ++removed;
  if (removed_pieces != nullptr) *removed_pieces = removed;
  return select_triangles(mesh, [&](std::size_t t) {
    return size[static_cast<std::size_t>(find_root(parent, mesh.triangles[t][0]))] >= min_triangles;
  });
}

}  // namespace hivox

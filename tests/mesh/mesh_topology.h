#pragma once
// Topology of an indexed triangle mesh, computed independently of the extractor: edge use,
// orientation, vertex links, components and the Euler characteristic.

#include <algorithm>
#include <array>
#include <cstdint>
#include <map>
#include <numeric>
#include <tuple>
#include <utility>
#include <vector>

namespace hivox::test {

struct MeshTopology {
  int64_t vertices = 0;
  int64_t edges = 0;  ///< undirected edges
  int64_t faces = 0;
  int64_t boundary_edges = 0;        ///< used by one triangle
  int64_t nonmanifold_edges = 0;     ///< used by more than two triangles
  int64_t misoriented_edges = 0;     ///< two triangles walking the edge in the same direction
  int64_t nonmanifold_vertices = 0;  ///< incident triangles not forming one fan (closed or open)
  int64_t unused_vertices = 0;
  int64_t degenerate_triangles = 0;  ///< a vertex index repeated
  int64_t components = 0;            ///< connected components of the used vertices
  int64_t euler() const { return vertices - unused_vertices - edges + faces; }
  bool closed_manifold() const {
    return boundary_edges == 0 && nonmanifold_edges == 0 && misoriented_edges == 0 &&
           nonmanifold_vertices == 0 && degenerate_triangles == 0;
  }
};

inline MeshTopology mesh_topology(int64_t vertex_count,
                                  const std::vector<std::array<int32_t, 3>>& triangles) {
  MeshTopology t;
  t.vertices = vertex_count;
  t.faces = static_cast<int64_t>(triangles.size());
  // Directed half-edges, sorted by their undirected key.
  struct HalfEdge {
    int32_t a, b;  // a < b
    bool forward;  // the triangle walks a -> b
  };
  std::vector<HalfEdge> half;
  half.reserve(triangles.size() * 3);
  std::vector<int32_t> parent(static_cast<std::size_t>(vertex_count));
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int32_t v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  std::vector<uint8_t> used(static_cast<std::size_t>(vertex_count), 0);
  // Per vertex: the link edges (b -> c for triangle (v, b, c)), to check fans.
  std::vector<std::vector<std::pair<int32_t, int32_t>>> link(
      static_cast<std::size_t>(vertex_count));
  for (const auto& tri : triangles) {
    if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) {
      ++t.degenerate_triangles;
      continue;
    }
    for (int k = 0; k < 3; ++k) {
      const int32_t a = tri[k], b = tri[(k + 1) % 3], c = tri[(k + 2) % 3];
      half.push_back({std::min(a, b), std::max(a, b), a < b});
      used[a] = 1;
      parent[find(a)] = find(b);
      link[a].push_back({b, c});
    }
  }
  std::sort(half.begin(), half.end(), [](const HalfEdge& x, const HalfEdge& y) {
    return std::tie(x.a, x.b) < std::tie(y.a, y.b);
  });
  for (std::size_t i = 0; i < half.size();) {
    std::size_t j = i;
    int forward = 0;
    while (j < half.size() && half[j].a == half[i].a && half[j].b == half[i].b)
      forward += half[j++].forward;
    const std::size_t n = j - i;
    ++t.edges;
    if (n == 1) ++t.boundary_edges;
    if (n > 2) ++t.nonmanifold_edges;
    if (n == 2 && forward != 1) ++t.misoriented_edges;
    i = j;
  }
  for (int64_t v = 0; v < vertex_count; ++v) {
    if (!used[v]) {
      ++t.unused_vertices;
      continue;
    }
    if (find(static_cast<int32_t>(v)) == v) ++t.components;
    // The link edges must chain into one path or one cycle.
    auto& l = link[static_cast<std::size_t>(v)];
    std::map<int32_t, int32_t> next;
    std::map<int32_t, int> in_degree;
    bool ok = true;
    for (const auto& [b, c] : l) {
      ok &= next.emplace(b, c).second;
      ok &= ++in_degree[c] == 1;
    }
    if (ok) {
      int32_t start = l.front().first;  // a path starts where nothing enters
      for (const auto& [b, c] : l)
        if (!in_degree.count(b)) start = b;
      std::size_t steps = 0;
      for (int32_t x = start; next.count(x) && steps <= l.size(); x = next[x]) {
        ++steps;
        if (next[x] == start) break;
      }
      ok = steps == l.size();
    }
    if (!ok) ++t.nonmanifold_vertices;
  }
  return t;
}

}  // namespace hivox::test

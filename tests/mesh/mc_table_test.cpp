#include "mesh/mc_table.h"

#include <gtest/gtest.h>

#include <array>
#include <bit>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include "mesh/mesh_topology.h"

namespace hivox {
namespace {

using mc::kMcTable;
using mc::McCase;
using Segment = std::pair<int, int>;  // directed: from one crossing edge to the next

bool inside(int cube_case, int corner) {
  return (cube_case >> corner) & 1;
}
bool crosses(int cube_case, int e) {
  return inside(cube_case, mc::mc_edge_corner(e, 0)) != inside(cube_case, mc::mc_edge_corner(e, 1));
}

std::vector<std::vector<int>> cycles_of(const McCase& c) {
  std::vector<std::vector<int>> out;
  int k = 0;
  for (int i = 0; i < c.cycle_count; ++i) {
    out.emplace_back(c.cycle_edges + k, c.cycle_edges + k + c.cycle_length[i]);
    k += c.cycle_length[i];
  }
  return out;
}

/// The face both edges lie on, or -1.
int common_face(int a, int b) {
  for (int f = 0; f < 6; ++f)
    if (mc::mc_edge_on_face(a, f) && mc::mc_edge_on_face(b, f)) return f;
  return -1;
}

/// Directed segments of a case that lie on face f (consecutive cycle edges on f).
std::set<Segment> segments_on_face(int cube_case, int f) {
  std::set<Segment> s;
  for (const auto& cyc : cycles_of(kMcTable.cases[cube_case]))
    for (std::size_t i = 0; i < cyc.size(); ++i) {
      const int a = cyc[i], b = cyc[(i + 1) % cyc.size()];
      if (common_face(a, b) == f) s.insert({a, b});
    }
  return s;
}

int crossings_on_face(int cube_case, int f) {
  int n = 0;
  for (int e = 0; e < 12; ++e) n += mc::mc_edge_on_face(e, f) && crosses(cube_case, e);
  return n;
}

/// Corner values +-1 (inside negative) and the trilinear interpolant's gradient.
std::array<double, 3> trilinear_gradient(int cube_case, const std::array<double, 3>& p) {
  std::array<double, 3> g{0, 0, 0};
  for (int c = 0; c < 8; ++c) {
    const double f = inside(cube_case, c) ? -1.0 : 1.0;
    const int b[3] = {c & 1, (c >> 1) & 1, (c >> 2) & 1};
    for (int k = 0; k < 3; ++k) {
      double w = b[k] ? 1.0 : -1.0;  // d/dp_k of the weight
      for (int j = 0; j < 3; ++j)
        if (j != k) w *= b[j] ? p[j] : 1.0 - p[j];
      g[k] += f * w;
    }
  }
  return g;
}

std::array<double, 3> edge_midpoint(int e) {
  const int c0 = mc::mc_edge_corner(e, 0);
  std::array<double, 3> p{double(c0 & 1), double((c0 >> 1) & 1), double((c0 >> 2) & 1)};
  p[mc::mc_edge_axis(e)] = 0.5;
  return p;
}

TEST(McTable, NumberingIsTheDocumentedOne) {
  const int expected[12][2] = {{0, 1}, {2, 3}, {4, 5}, {6, 7}, {0, 2}, {1, 3},
                               {4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
  for (int e = 0; e < 12; ++e) {
    EXPECT_EQ(mc::mc_edge_corner(e, 0), expected[e][0]) << "edge " << e;
    EXPECT_EQ(mc::mc_edge_corner(e, 1), expected[e][1]) << "edge " << e;
    EXPECT_EQ(mc::mc_edge_between(expected[e][0], expected[e][1]), e);
  }
  // Face corners are counter-clockwise seen from outside: (c1 - c0) x (c2 - c1) is the outward
  // normal.
  for (int f = 0; f < 6; ++f) {
    int p[4][3];
    for (int i = 0; i < 4; ++i) {
      const int c = mc::mc_face_corner(f, i);
      p[i][0] = c & 1, p[i][1] = (c >> 1) & 1, p[i][2] = (c >> 2) & 1;
      EXPECT_EQ((c >> (f / 2)) & 1, f % 2) << "face " << f;
    }
    const int a[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
    const int b[3] = {p[2][0] - p[1][0], p[2][1] - p[1][1], p[2][2] - p[1][2]};
    const int n[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                      a[0] * b[1] - a[1] * b[0]};
    for (int k = 0; k < 3; ++k)
      EXPECT_EQ(n[k], k == f / 2 ? (f % 2 ? 1 : -1) : 0) << "face " << f << " axis " << k;
  }
}

TEST(McTable, EveryCrossingEdgeIsUsedExactlyOnceAndNoOther) {
  for (int c = 0; c < 256; ++c) {
    const McCase& mcase = kMcTable.cases[c];
    std::set<int> expected, in_cycles, in_triangles;
    for (int e = 0; e < 12; ++e)
      if (crosses(c, e)) expected.insert(e);
    int total = 0;
    for (const auto& cyc : cycles_of(mcase))
      for (const int e : cyc) {
        EXPECT_TRUE(in_cycles.insert(e).second) << "case " << c << ": edge " << e << " twice";
        ++total;
      }
    for (int t = 0; t < mcase.triangle_count; ++t)
      for (int k = 0; k < 3; ++k) in_triangles.insert(mcase.triangles[t][k]);
    EXPECT_EQ(in_cycles, expected) << "case " << c;
    EXPECT_EQ(in_triangles, expected) << "case " << c;
    EXPECT_EQ(total, std::popcount(static_cast<unsigned>(mcase.edge_mask))) << "case " << c;
    for (int e = 0; e < 12; ++e) EXPECT_EQ(((mcase.edge_mask >> e) & 1) != 0, crosses(c, e));
  }
  EXPECT_EQ(kMcTable.cases[0].triangle_count, 0);
  EXPECT_EQ(kMcTable.cases[255].triangle_count, 0);
}

TEST(McTable, CyclesAreClosedWalksOverFacesAndTrianglesFanThem) {
  for (int c = 0; c < 256; ++c) {
    const McCase& mcase = kMcTable.cases[c];
    int triangles = 0;
    std::multiset<Segment> boundary;  // directed cycle segments
    for (const auto& cyc : cycles_of(mcase)) {
      ASSERT_GE(cyc.size(), 3u) << "case " << c;
      triangles += static_cast<int>(cyc.size()) - 2;
      for (std::size_t i = 0; i < cyc.size(); ++i) {
        const int a = cyc[i], b = cyc[(i + 1) % cyc.size()];  // includes last -> first
        EXPECT_GE(common_face(a, b), 0)
            << "case " << c << ": step " << a << "->" << b << " leaves the cube surface";
        boundary.insert({a, b});
      }
    }
    ASSERT_EQ(mcase.triangle_count, triangles) << "case " << c;
    // Half-edges of the triangles: interior ones cancel in opposite pairs, the rest are
    // exactly the cycles, walked in the same direction (each cycle is a disc).
    std::multiset<Segment> half;
    for (int t = 0; t < mcase.triangle_count; ++t)
      for (int k = 0; k < 3; ++k) {
        const Segment s{mcase.triangles[t][k], mcase.triangles[t][(k + 1) % 3]};
        const auto opposite = half.find({s.second, s.first});
        if (opposite != half.end())
          half.erase(opposite);
        else
          half.insert(s);
      }
    EXPECT_EQ(half, boundary) << "case " << c;
  }
}

TEST(McTable, AmbiguousFacesKeepInsideCornersApart) {
  int ambiguous = 0;
  for (int c = 0; c < 256; ++c)
    for (int f = 0; f < 6; ++f) {
      const std::set<Segment> segs = segments_on_face(c, f);
      const int n = crossings_on_face(c, f);
      ASSERT_EQ(static_cast<int>(segs.size()) * 2, n) << "case " << c << " face " << f;
      if (n != 4) continue;
      ++ambiguous;
      for (const auto& [a, b] : segs) {
        // Both edges touch the same corner, and that corner is inside.
        int shared = -1;
        for (int ea = 0; ea < 2; ++ea)
          for (int eb = 0; eb < 2; ++eb)
            if (mc::mc_edge_corner(a, ea) == mc::mc_edge_corner(b, eb))
              shared = mc::mc_edge_corner(a, ea);
        ASSERT_GE(shared, 0) << "case " << c << " face " << f;
        EXPECT_TRUE(inside(c, shared)) << "case " << c << " face " << f;
      }
    }
  EXPECT_GT(ambiguous, 0);
}

TEST(McTable, NeighbouringCellsAgreeOnTheSharedFace) {
  // For cell A and its +axis neighbour B the shared face is A's face (axis, 1) and B's face
  // (axis, 0). Whatever B's other four corners are, both must draw the same segments there,
  // walked in opposite directions.
  for (int c = 0; c < 256; ++c)
    for (int axis = 0; axis < 3; ++axis) {
      const int bit = 1 << axis;
      std::set<Segment> a_segs;
      for (const auto& [a, b] : segments_on_face(c, 2 * axis + 1)) {
        // The same grid edge in B: corners moved down by one along `axis`.
        const int a0 = mc::mc_edge_corner(a, 0) & ~bit, a1 = mc::mc_edge_corner(a, 1) & ~bit;
        const int b0 = mc::mc_edge_corner(b, 0) & ~bit, b1 = mc::mc_edge_corner(b, 1) & ~bit;
        a_segs.insert({mc::mc_edge_between(b0, b1), mc::mc_edge_between(a0, a1)});  // reversed
      }
      for (int far = 0; far < 16; ++far) {
        int nb = 0, k = 0;
        for (int corner = 0; corner < 8; ++corner) {
          const bool in = (corner & bit) ? ((far >> k++) & 1) : inside(c, corner | bit);
          nb |= static_cast<int>(in) << corner;
        }
        EXPECT_EQ(segments_on_face(nb, 2 * axis), a_segs)
            << "case " << c << " and its +" << axis << " neighbour " << nb;
      }
    }
}

TEST(McTable, TrianglesFaceThePositiveSide) {
  // Corner values +-1, vertices at edge midpoints (where the trilinear interpolant crosses
  // zero). Each cycle's vector area and each triangle's normal point along the interpolant's
  // gradient, i.e. towards the positive side.
  for (int c = 1; c < 255; ++c) {
    const McCase& mcase = kMcTable.cases[c];
    for (const auto& cyc : cycles_of(mcase)) {
      std::array<double, 3> area{0, 0, 0}, centre{0, 0, 0};
      for (std::size_t i = 0; i < cyc.size(); ++i) {
        const auto p = edge_midpoint(cyc[i]), q = edge_midpoint(cyc[(i + 1) % cyc.size()]);
        area[0] += p[1] * q[2] - p[2] * q[1];
        area[1] += p[2] * q[0] - p[0] * q[2];
        area[2] += p[0] * q[1] - p[1] * q[0];
        for (int k = 0; k < 3; ++k) centre[k] += p[k] / static_cast<double>(cyc.size());
      }
      const auto g = trilinear_gradient(c, centre);
      EXPECT_GT(area[0] * g[0] + area[1] * g[1] + area[2] * g[2], 0.0) << "case " << c;
    }
    for (int t = 0; t < mcase.triangle_count; ++t) {
      const auto a = edge_midpoint(mcase.triangles[t][0]);
      const auto b = edge_midpoint(mcase.triangles[t][1]);
      const auto d = edge_midpoint(mcase.triangles[t][2]);
      const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
      const double v[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
      const double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                           u[0] * v[1] - u[1] * v[0]};
      // The gradient at each vertex is along its edge, from the inside end to the outside one.
      for (int k = 0; k < 3; ++k) {
        const int e = mcase.triangles[t][k];
        const double sign = inside(c, mc::mc_edge_corner(e, 0)) ? 1.0 : -1.0;
        EXPECT_GT(sign * n[mc::mc_edge_axis(e)], -1e-12)
            << "case " << c << " triangle " << t << " vertex on edge " << e;
      }
    }
  }
}

TEST(McTable, ComplementaryCaseFlipsOrientationWhereNoFaceIsAmbiguous) {
  int checked = 0;
  for (int c = 1; c < 255; ++c) {
    bool ambiguous = false;
    for (int f = 0; f < 6; ++f) ambiguous |= crossings_on_face(c, f) == 4;
    std::set<Segment> segs, reversed;
    for (int f = 0; f < 6; ++f)
      for (const auto& [a, b] : segments_on_face(c, f)) segs.insert({a, b});
    for (int f = 0; f < 6; ++f)
      for (const auto& [a, b] : segments_on_face(255 - c, f)) reversed.insert({b, a});
    if (ambiguous) {
      // The complement separates the other corners: the surfaces differ on that face.
      EXPECT_NE(segs, reversed) << "case " << c;
      continue;
    }
    EXPECT_EQ(segs, reversed) << "case " << c;
    ++checked;
  }
  EXPECT_GT(checked, 100);
}

TEST(McTable, FanDiagonalsNeverJoinTheTwoSegmentsOfAnAmbiguousFace) {
  // Such a diagonal could be drawn by the cell on the other side of that face as well, and
  // the edge would belong to four triangles.
  for (int c = 0; c < 256; ++c) {
    const McCase& mcase = kMcTable.cases[c];
    std::set<std::pair<int, int>> sides;
    for (const auto& cyc : cycles_of(mcase))
      for (std::size_t i = 0; i < cyc.size(); ++i) {
        const int a = cyc[i], b = cyc[(i + 1) % cyc.size()];
        sides.insert({std::min(a, b), std::max(a, b)});
      }
    for (int t = 0; t < mcase.triangle_count; ++t)
      for (int k = 0; k < 3; ++k) {
        const int a = mcase.triangles[t][k], b = mcase.triangles[t][(k + 1) % 3];
        if (sides.count({std::min(a, b), std::max(a, b)})) continue;  // not a diagonal
        const int f = common_face(a, b);
        EXPECT_TRUE(f < 0 || crossings_on_face(c, f) != 4)
            << "case " << c << ": diagonal " << a << "-" << b << " on ambiguous face " << f;
      }
  }
}

TEST(McTable, RandomSignGridsGiveClosedOrientedManifolds) {
  // Cells of a grid with random corner signs (outside on the border) share vertices by grid
  // edge: the surface must be closed, 2-manifold and consistently oriented everywhere.
  constexpr int n = 10;
  std::mt19937 rng(7);
  for (int trial = 0; trial < 200; ++trial) {
    const double p_inside = 0.2 + 0.6 * (trial % 7) / 6.0;
    std::bernoulli_distribution coin(p_inside);
    std::vector<uint8_t> in(n * n * n, 0);
    auto at = [&](int x, int y, int z) { return (z * n + y) * n + x; };
    for (int z = 1; z < n - 1; ++z)
      for (int y = 1; y < n - 1; ++y)
        for (int x = 1; x < n - 1; ++x) in[at(x, y, z)] = coin(rng);
    std::vector<int32_t> vertex_of_edge(n * n * n * 3, -1);
    int32_t vertices = 0;
    std::vector<std::array<int32_t, 3>> triangles;
    for (int z = 0; z + 1 < n; ++z)
      for (int y = 0; y + 1 < n; ++y)
        for (int x = 0; x + 1 < n; ++x) {
          int c = 0;
          for (int k = 0; k < 8; ++k)
            c |= in[at(x + (k & 1), y + ((k >> 1) & 1), z + (k >> 2))] << k;
          const McCase& mcase = kMcTable.cases[c];
          for (int t = 0; t < mcase.triangle_count; ++t) {
            std::array<int32_t, 3> tri{};
            for (int k = 0; k < 3; ++k) {
              const int e = mcase.triangles[t][k];
              const int c0 = mc::mc_edge_corner(e, 0);
              const int id =
                  at(x + (c0 & 1), y + ((c0 >> 1) & 1), z + (c0 >> 2)) * 3 + mc::mc_edge_axis(e);
              if (vertex_of_edge[id] < 0) vertex_of_edge[id] = vertices++;
              tri[k] = vertex_of_edge[id];
            }
            triangles.push_back(tri);
          }
        }
    const test::MeshTopology topo = test::mesh_topology(vertices, triangles);
    ASSERT_TRUE(topo.closed_manifold())
        << "trial " << trial << ": boundary " << topo.boundary_edges << ", non-manifold edges "
        << topo.nonmanifold_edges << ", misoriented " << topo.misoriented_edges
        << ", non-manifold vertices " << topo.nonmanifold_vertices;
    ASSERT_EQ(topo.unused_vertices, 0);
    // Each closed orientable component has an even Euler characteristic.
    ASSERT_EQ(topo.euler() % 2, 0) << "trial " << trial;
  }
}

}  // namespace
}  // namespace hivox

#pragma once
// Marching-cubes case tables, generated at compile time from a face-consistent rule instead of
// being transcribed from a paper.
//
// Numbering (used everywhere in the mesh module):
//
//   corner c = 0..7 sits at (c & 1, (c >> 1) & 1, (c >> 2) & 1) in cell units, i.e. bit 0 is x,
//   bit 1 is y, bit 2 is z:
//
//            6 ---------- 7          z
//           /|           /|          |  y
//          4 ---------- 5 |          | /
//          | 2 ---------|-3          |/
//          |/           |/           +---- x
//          0 ---------- 1
//
//   edge e = 4 * axis + j (axis 0 = x, 1 = y, 2 = z): the edge parallel to `axis` whose two
//   other coordinates are given by j, bit 0 for the lower-numbered other axis and bit 1 for the
//   higher one. Its lower end is corner `mc_edge_corner(e, 0)`, its upper end the same corner
//   plus 1 along `axis`. So the x edges are 0: 0-1, 1: 2-3, 2: 4-5, 3: 6-7; the y edges are
//   4: 0-2, 5: 1-3, 6: 4-6, 7: 5-7; the z edges are 8: 0-4, 9: 1-5, 10: 2-6, 11: 3-7.
//
//   A case index has bit c set when corner c is inside (TSDF < 0).
//
// Rule. On each of the six faces, looked at from outside the cube, walk the 4 corners
// counter-clockwise. An edge walked from an outside to an inside corner "enters" the inside;
// one walked from inside to outside "leaves" it. Each entering crossing is joined to the next
// leaving crossing further along the walk. With 2 crossings this is the one possible segment;
// with 4 (an ambiguous face: inside corners diagonally opposite) it cuts off each inside corner
// on its own, i.e. the inside corners are always kept apart. The rule reads only the face's own
// corner signs, so the two cells sharing a face draw the same segments there and the surface
// has no holes between cells.
//
// Every crossing edge lies on two faces, which walk it in opposite directions: it is the start
// of exactly one segment and the end of exactly one. The segments therefore chain into closed
// directed cycles, each fan-triangulated. With this direction (inside on the right of each
// segment seen from outside) the cycles run counter-clockwise around the outside region, so a
// triangle (a, b, c) has its normal (b - a) x (c - a) pointing to the positive (free-space)
// side. The fan apex of each cycle is chosen so that (1) no fan diagonal joins the two separate
// segments of an ambiguous face: the cell on the other side of that face could draw the same
// diagonal, and the edge would then belong to four triangles; and (2) no triangle is folded
// over: with vertices at the edge midpoints, each triangle's normal points, along each of its
// vertices' edges, from the inside end to the outside end.
//
// The tables are plain arrays so that a CUDA driver can copy `kMcTable` to constant memory.

#include <cstdint>

#include "hivox/core/hd.h"

namespace hivox::mc {

/// Most triangles of one case. The rule yields at most 5 (cycles of up to 7 crossings, like the
/// classic tables); evaluating the generator with a smaller bound fails to compile.
inline constexpr int kMaxTriangles = 5;
inline constexpr int kMaxCycles = 4;  ///< each cycle has >= 3 of the <= 12 crossings

/// The two axes other than `axis`, lower-numbered first.
HIVOX_HD constexpr int other_axis(int axis, int k) {
  return k == 0 ? (axis == 0 ? 1 : 0) : (axis == 2 ? 1 : 2);
}

/// Corner at end `end` (0 lower, 1 upper) of cube edge `e`.
HIVOX_HD constexpr int mc_edge_corner(int e, int end) {
  const int axis = e / 4, j = e % 4;
  const int lower = ((j & 1) << other_axis(axis, 0)) | ((j >> 1) << other_axis(axis, 1));
  return lower | (end << axis);
}

HIVOX_HD constexpr int mc_edge_axis(int e) {
  return e / 4;
}

/// The cube edge joining two corners that differ in exactly one bit.
HIVOX_HD constexpr int mc_edge_between(int c0, int c1) {
  const int diff = c0 ^ c1;
  const int axis = diff == 1 ? 0 : (diff == 2 ? 1 : 2);
  const int lower = c0 & c1;
  const int j = ((lower >> other_axis(axis, 0)) & 1) | (((lower >> other_axis(axis, 1)) & 1) << 1);
  return 4 * axis + j;
}

/// Corners of face f = 2 * axis + side (side 1 = the face at +axis), counter-clockwise seen
/// from outside the cube.
HIVOX_HD constexpr int mc_face_corner(int f, int i) {
  const int axis = f / 2, side = f % 2;
  // (axis, p, q) right-handed: p x q = +axis.
  const int p = (axis + 1) % 3, q = (axis + 2) % 3;
  constexpr int kU[4] = {0, 1, 1, 0}, kV[4] = {0, 0, 1, 1};
  // Seen from +axis the order (0,0) (1,0) (1,1) (0,1) in (p, q) is counter-clockwise; seen from
  // -axis it is clockwise, so the -axis face walks it with p and q swapped.
  const int u = side ? kU[i] : kV[i], v = side ? kV[i] : kU[i];
  return (side << axis) | (u << p) | (v << q);
}

/// Whether cube edge `e` lies on face `f`.
HIVOX_HD constexpr bool mc_edge_on_face(int e, int f) {
  const int axis = f / 2, side = f % 2;
  return mc_edge_axis(e) != axis && ((mc_edge_corner(e, 0) >> axis) & 1) == side;
}

/// One corner-sign case: the crossing cycles and their triangles (cube edge indices).
struct McCase {
  int8_t cycle_count = 0;
  int8_t cycle_length[kMaxCycles] = {};
  int8_t cycle_edges[12] = {};  ///< the cycles one after another, each in walking order
  int8_t triangle_count = 0;
  int8_t triangles[kMaxTriangles][3] = {};
  uint16_t edge_mask = 0;  ///< bit e set when edge e has a sign change
};

struct McTable {
  McCase cases[256];
};

namespace detail {

/// Segments of `cube_case` on face f: pairs (start edge, end edge), written to `out`; returns
/// how many (0, 1 or 2).
constexpr int face_segments(int cube_case, int f, int out[2][2]) {
  bool inside[4] = {};
  int edge[4] = {};
  for (int i = 0; i < 4; ++i) {
    inside[i] = (cube_case >> mc_face_corner(f, i)) & 1;
    edge[i] = mc_edge_between(mc_face_corner(f, i), mc_face_corner(f, (i + 1) % 4));
  }
  int n = 0;
  for (int i = 0; i < 4; ++i) {
    if (inside[i] || !inside[(i + 1) % 4]) continue;  // edge i does not enter the inside
    for (int k = 1; k < 4; ++k) {
      const int m = (i + k) % 4;
      if (inside[m] && !inside[(m + 1) % 4]) {  // the next leaving edge
        out[n][0] = edge[i];
        out[n][1] = edge[m];
        ++n;
        break;
      }
    }
  }
  return n;
}

/// Whether crossing edges a and b lie on a common face that has two segments.
constexpr bool on_common_ambiguous_face(int cube_case, int a, int b) {
  for (int f = 0; f < 6; ++f) {
    int seg[2][2] = {};
    if (mc_edge_on_face(a, f) && mc_edge_on_face(b, f) && face_segments(cube_case, f, seg) == 2)
      return true;
  }
  return false;
}

/// Twice the midpoint of cube edge e (integer coordinates 0, 1 or 2).
constexpr void edge_midpoint2(int e, int p[3]) {
  const int c = mc_edge_corner(e, 0);
  for (int k = 0; k < 3; ++k) p[k] = 2 * ((c >> k) & 1);
  p[mc_edge_axis(e)] = 1;
}

/// Whether triangle (a, b, c) of cube edges, with vertices at the edge midpoints, is unfolded:
/// along each of its vertices' edges its normal points from the inside end to the outside end
/// (where the TSDF gradient points at that vertex).
constexpr bool triangle_is_unfolded(int cube_case, int a, int b, int c) {
  int pa[3] = {}, pb[3] = {}, pc[3] = {};
  edge_midpoint2(a, pa);
  edge_midpoint2(b, pb);
  edge_midpoint2(c, pc);
  const int u[3] = {pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]};
  const int v[3] = {pc[0] - pa[0], pc[1] - pa[1], pc[2] - pa[2]};
  const int n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                    u[0] * v[1] - u[1] * v[0]};
  const int corners[3] = {a, b, c};
  for (const int e : corners) {
    const int inside_sign = ((cube_case >> mc_edge_corner(e, 0)) & 1) ? 1 : -1;
    if (inside_sign * n[mc_edge_axis(e)] < 0) return false;
  }
  return true;
}

/// Whether the fan of `cycle` from vertex `apex` is acceptable: no diagonal joins the two
/// segments of an ambiguous face, and no triangle is folded.
constexpr bool fan_is_good(int cube_case, const int* cycle, int len, int apex) {
  for (int k = 2; k + 1 < len; ++k)
    if (on_common_ambiguous_face(cube_case, cycle[apex], cycle[(apex + k) % len])) return false;
  for (int k = 1; k + 1 < len; ++k)
    if (!triangle_is_unfolded(cube_case, cycle[apex], cycle[(apex + k) % len],
                              cycle[(apex + k + 1) % len]))
      return false;
  return true;
}

/// Not constexpr: calling it during the table's constant evaluation is a compile error.
inline void no_acceptable_fan() {}

constexpr McCase make_case(int cube_case) {
  McCase c;
  int next[12] = {};
  for (int e = 0; e < 12; ++e) {
    next[e] = -1;
    const bool in0 = (cube_case >> mc_edge_corner(e, 0)) & 1;
    const bool in1 = (cube_case >> mc_edge_corner(e, 1)) & 1;
    if (in0 != in1) c.edge_mask = static_cast<uint16_t>(c.edge_mask | (1u << e));
  }
  for (int f = 0; f < 6; ++f) {
    int seg[2][2] = {};
    const int n = face_segments(cube_case, f, seg);
    for (int s = 0; s < n; ++s) next[seg[s][0]] = seg[s][1];
  }
  bool used[12] = {};
  int written = 0;
  for (int start = 0; start < 12; ++start) {
    if (next[start] < 0 || used[start]) continue;
    int cycle[12] = {};
    int len = 0;
    for (int e = start; !used[e]; e = next[e]) {
      used[e] = true;
      cycle[len++] = e;
    }
    // Fan apex: the first vertex of the cycle whose fan keeps ambiguous faces apart and has no
    // folded triangle. Every case has one; if a change of rule broke that, the table would
    // stop compiling here.
    int apex = -1;
    for (int a = 0; a < len && apex < 0; ++a)
      if (fan_is_good(cube_case, cycle, len, a)) apex = a;
    if (apex < 0) no_acceptable_fan();
    c.cycle_length[c.cycle_count++] = static_cast<int8_t>(len);
    for (int k = 0; k < len; ++k) c.cycle_edges[written++] = static_cast<int8_t>(cycle[k]);
    for (int k = 1; k + 1 < len; ++k) {
      int8_t* t = c.triangles[c.triangle_count++];
      t[0] = static_cast<int8_t>(cycle[apex]);
      t[1] = static_cast<int8_t>(cycle[(apex + k) % len]);
      t[2] = static_cast<int8_t>(cycle[(apex + k + 1) % len]);
    }
  }
  return c;
}

constexpr McTable make_table() {
  McTable t;
  for (int i = 0; i < 256; ++i) t.cases[i] = make_case(i);
  return t;
}

}  // namespace detail

/// The 256 cases, generated at compile time.
inline constexpr McTable kMcTable = detail::make_table();

}  // namespace hivox::mc

#pragma once
/// @file
/// An indexed triangle mesh in the world frame, as extracted from the map and read from or
/// written to PLY/OFF files.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "hivox/core/image.h"
#include "hivox/core/math.h"

namespace hivox {

/// Vertices (one entry per vertex in each non-empty attribute array) and triangles (indices
/// into the vertices, counter-clockwise seen from the side the normals point to).
struct TriangleMesh {
  std::vector<Vec3f> positions_w;  ///< metres, world frame
  std::vector<Vec3f> normals_w;    ///< unit length, world frame; empty when not computed
  std::vector<Rgb8> colors;        ///< sRGB; empty when the mesh has no colour
  std::vector<uint8_t> levels;     ///< resolution level each vertex was extracted at, or empty
  std::vector<std::array<int32_t, 3>> triangles;

  int64_t vertex_count() const { return static_cast<int64_t>(positions_w.size()); }
  int64_t triangle_count() const { return static_cast<int64_t>(triangles.size()); }
  bool empty() const { return positions_w.empty(); }

  /// Throws `Error(InvalidArgument)` when an attribute array is neither empty nor one entry per
  /// vertex, or a triangle index is out of range; the message names the array.
  void validate() const;
  /// validate() for a writer: the error names `path`, which cannot be written from this mesh.
  void validate_for_writing(const std::string& path) const;
};

/// An axis-aligned box in the world frame, metres (corners included).
struct Box3f {
  Vec3f min_m, max_m;
  bool contains(const Vec3f& p) const {
    return p.x >= min_m.x && p.y >= min_m.y && p.z >= min_m.z && p.x <= max_m.x && p.y <= max_m.y &&
           p.z <= max_m.z;
  }
  /// Throws `Error(InvalidArgument)` unless finite with min <= max on every axis.
  void validate(const char* what = "bounding box") const;
};

/// The triangles of `mesh` whose three corners lie inside `box`, with the vertices they use
/// (attributes kept, order kept).
TriangleMesh crop_mesh(const TriangleMesh& mesh, const Box3f& box);

/// `mesh` without its connected pieces of fewer than `min_triangles` triangles (floating specks
/// of noise). Triangles sharing a vertex are connected, and so are vertices closer than about
/// `join_distance_m` (within one grid cell of that size): pieces that meet across a change of
/// resolution level, whose vertices are not shared, stay one piece. `removed_pieces` (optional)
/// receives the number of pieces removed. Order is kept.
TriangleMesh remove_small_pieces(const TriangleMesh& mesh, int64_t min_triangles,
                                 float join_distance_m, int64_t* removed_pieces = nullptr);

}  // namespace hivox

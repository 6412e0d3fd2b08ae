#pragma once
/// @file
/// An indexed triangle mesh in the world frame, as extracted from the map and read from or
/// written to PLY/OFF files.

#include <array>
#include <cstdint>
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
};

}  // namespace hivox

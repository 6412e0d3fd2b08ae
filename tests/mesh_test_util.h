#pragma once
// Meshes with known geometry for tests.

#include <cstdint>

#include "hivox/mesh/triangle_mesh.h"

namespace hivox::test {

/// A w x h grid of `cell`-metre squares (two triangles each) in the plane at height z, from the
/// origin; vertex (x, y) is number y * (w + 1) + x.
inline TriangleMesh plane_mesh(int w, int h, float cell, float z = 0.0f) {
  TriangleMesh m;
  for (int y = 0; y <= h; ++y)
    for (int x = 0; x <= w; ++x)
      m.positions_w.push_back({static_cast<float>(x) * cell, static_cast<float>(y) * cell, z});
  auto at = [&](int x, int y) { return static_cast<int32_t>(y * (w + 1) + x); };
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      m.triangles.push_back({at(x, y), at(x + 1, y), at(x + 1, y + 1)});
      m.triangles.push_back({at(x, y), at(x + 1, y + 1), at(x, y + 1)});
    }
  return m;
}

}  // namespace hivox::test

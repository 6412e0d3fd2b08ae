#include "hivox/mesh/triangle_mesh.h"

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

}  // namespace hivox

#include "hivox/io/obj.h"

#include <cstdint>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "hivox/core/error.h"
#include "hivox/io/atomic_file.h"

namespace hivox {

void write_obj(const std::filesystem::path& path, const TriangleMesh& mesh) {
  mesh.validate_for_writing(path.string());
  const bool normals = !mesh.normals_w.empty(), colors = !mesh.colors.empty();
  fmt::memory_buffer out;
  fmt::format_to(std::back_inserter(out), "# written by hivox: {} vertices, {} triangles\n",
                 mesh.vertex_count(), mesh.triangle_count());
  for (std::size_t i = 0; i < mesh.positions_w.size(); ++i) {
    const Vec3f& p = mesh.positions_w[i];
    if (colors) {
      const Rgb8& c = mesh.colors[i];
      fmt::format_to(std::back_inserter(out), "v {} {} {} {:.4f} {:.4f} {:.4f}\n", p.x, p.y, p.z,
                     c.r / 255.0f, c.g / 255.0f, c.b / 255.0f);
    } else {
      fmt::format_to(std::back_inserter(out), "v {} {} {}\n", p.x, p.y, p.z);
    }
  }
  if (normals)
    for (const Vec3f& n : mesh.normals_w)
      fmt::format_to(std::back_inserter(out), "vn {} {} {}\n", n.x, n.y, n.z);
  for (const auto& t : mesh.triangles) {
    const int64_t a = int64_t{t[0]} + 1, b = int64_t{t[1]} + 1, c = int64_t{t[2]} + 1;
    if (normals)
      fmt::format_to(std::back_inserter(out), "f {0}//{0} {1}//{1} {2}//{2}\n", a, b, c);
    else
      fmt::format_to(std::back_inserter(out), "f {} {} {}\n", a, b, c);
  }
  write_file_atomically(path, std::string_view(out.data(), out.size()));
}

}  // namespace hivox

#include "hivox/io/obj.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "hivox/core/error.h"
#include "hivox/io/atomic_file.h"
#include "hivox/io/text_lines.h"

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

namespace hivox {

namespace {

/// A face corner's vertex: the number before the first '/', 1-based, negative from the end.
int32_t corner_index(const std::filesystem::path& path, const TextLine& line, std::size_t field,
                     std::size_t vertices) {
  const std::string& text = line.fields[field];
  const std::string number = text.substr(0, text.find('/'));
  const double v = parse_double(path, TextLine{line.number, {number}}, 0, "face vertex index");
  const double index = v < 0 ? static_cast<double>(vertices) + v : v - 1;
  if (v == 0 || v != std::floor(v) || index < 0 || index >= static_cast<double>(vertices))
    fail(ErrorCode::InvalidData, "{}:{}: face vertex '{}' is not one of the {} vertices before it",
         path.string(), line.number, text, vertices);
  return static_cast<int32_t>(index);
}

}  // namespace

TriangleMesh read_obj(const std::filesystem::path& path) {
  const std::vector<TextLine> lines = read_text_lines(path);
  TriangleMesh mesh;
  bool all_colored = true;
  std::vector<int32_t> corners;
  for (const TextLine& l : lines) {
    const std::string& key = l.fields.front();
    if (key == "v") {
      if (l.fields.size() < 4)
        fail(ErrorCode::InvalidData, "{}:{}: a vertex needs x y z", path.string(), l.number);
      auto value = [&](std::size_t k, const char* what) {
        return static_cast<float>(parse_double(path, l, k, what));
      };
      mesh.positions_w.push_back({value(1, "x"), value(2, "y"), value(3, "z")});
      if (l.fields.size() >= 7) {
        Rgb8 c;
        uint8_t* rgb[3] = {&c.r, &c.g, &c.b};
        for (int k = 0; k < 3; ++k)
          *rgb[k] = static_cast<uint8_t>(
              std::clamp(std::round(parse_double(path, l, 4 + k, "colour") * 255.0), 0.0, 255.0));
        mesh.colors.push_back(c);
      } else {
        all_colored = false;
      }
    } else if (key == "f") {
      if (l.fields.size() < 4)
        fail(ErrorCode::InvalidData, "{}:{}: a face needs at least 3 corners", path.string(),
             l.number);
      corners.clear();
      for (std::size_t k = 1; k < l.fields.size(); ++k)
        corners.push_back(corner_index(path, l, k, mesh.positions_w.size()));
      for (std::size_t k = 1; k + 1 < corners.size(); ++k)  // a fan
        mesh.triangles.push_back({corners[0], corners[k], corners[k + 1]});
    }
    // vn, vt, o, g, s, usemtl, mtllib, l, p: nothing this mesh keeps.
  }
  if (mesh.positions_w.empty())
    fail(ErrorCode::InvalidData, "{}: no vertices ('v x y z' lines)", path.string());
  if (!all_colored) mesh.colors.clear();
  return mesh;
}

}  // namespace hivox

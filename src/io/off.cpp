#include "hivox/io/off.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "hivox/core/error.h"
#include "hivox/io/text_lines.h"

namespace hivox {

namespace {

/// Drops an end-of-line comment ('#' and what follows) from the fields of a line.
void strip_comment(TextLine& line) {
  for (std::size_t i = 0; i < line.fields.size(); ++i) {
    const auto hash = line.fields[i].find('#');
    if (hash == std::string::npos) continue;
    line.fields[i].resize(hash);
    line.fields.resize(line.fields[i].empty() ? i : i + 1);
    return;
  }
}

int64_t parse_count(const std::filesystem::path& path, const TextLine& line, std::size_t i,
                    const char* what) {
  const double v = parse_double(path, line, i, what);
  if (v < 0 || v != std::floor(v) || v > 2e9)
    fail(ErrorCode::InvalidData, "{}:{}: {} '{}' is not a valid count", path.string(), line.number,
         what, line.fields[i]);
  return static_cast<int64_t>(v);
}

}  // namespace

TriangleMesh read_off(const std::filesystem::path& path) {
  std::vector<TextLine> lines = read_text_lines(path);
  for (TextLine& l : lines) strip_comment(l);
  std::erase_if(lines, [](const TextLine& l) { return l.fields.empty(); });
  if (lines.empty())
    fail(ErrorCode::InvalidData, "{}: empty file, expected an OFF header", path.string());

  // Header keyword: [C][N]OFF, optionally followed by the counts on the same line.
  TextLine head = lines.front();
  const std::string keyword = head.fields.front();
  const bool has_color = keyword == "COFF" || keyword == "CNOFF" || keyword == "NCOFF";
  const bool has_normal = keyword == "NOFF" || keyword == "CNOFF" || keyword == "NCOFF";
  if (keyword != "OFF" && !has_color && !has_normal)
    fail(ErrorCode::InvalidData, "{}:{}: expected an OFF header keyword, found '{}'", path.string(),
         head.number, keyword);
  if (head.fields.size() > 1 && head.fields[1] == "BINARY")
    fail(ErrorCode::Unsupported, "{}: binary OFF is not supported", path.string());
  std::size_t next = 1;
  TextLine counts = head;
  counts.fields.erase(counts.fields.begin());
  if (counts.fields.empty()) {
    if (lines.size() < 2)
      fail(ErrorCode::InvalidData, "{}: missing the 'vertices faces edges' line", path.string());
    counts = lines[1];
    next = 2;
  }
  const int64_t nv = parse_count(path, counts, 0, "vertex count");
  const int64_t nf = parse_count(path, counts, 1, "face count");
  if (lines.size() < next + static_cast<std::size_t>(nv + nf))
    fail(ErrorCode::InvalidData,
         "{}: header declares {} vertices and {} faces but only {} lines follow", path.string(), nv,
         nf, lines.size() - next);

  TriangleMesh mesh;
  mesh.positions_w.resize(static_cast<std::size_t>(nv));
  if (has_normal) mesh.normals_w.resize(static_cast<std::size_t>(nv));
  if (has_color) mesh.colors.resize(static_cast<std::size_t>(nv));
  for (int64_t i = 0; i < nv; ++i) {
    const TextLine& l = lines[next + static_cast<std::size_t>(i)];
    auto value = [&](std::size_t k, const char* what) {
      return static_cast<float>(parse_double(path, l, k, what));
    };
    mesh.positions_w[static_cast<std::size_t>(i)] = {value(0, "x"), value(1, "y"), value(2, "z")};
    std::size_t k = 3;
    if (has_normal) {
      mesh.normals_w[static_cast<std::size_t>(i)] = {value(3, "nx"), value(4, "ny"),
                                                     value(5, "nz")};
      k = 6;
    }
    if (has_color) {
      // Integer channels are 0..255; fractional ones (a '.' in the field) are 0..1.
      uint8_t rgb[3];
      for (int c = 0; c < 3; ++c) {
        double v = parse_double(path, l, k + static_cast<std::size_t>(c), "colour");
        if (l.fields[k + static_cast<std::size_t>(c)].find('.') != std::string::npos) v *= 255.0;
        rgb[c] = static_cast<uint8_t>(std::clamp(std::round(v), 0.0, 255.0));
      }
      mesh.colors[static_cast<std::size_t>(i)] = {rgb[0], rgb[1], rgb[2]};
    }
  }
  mesh.triangles.reserve(static_cast<std::size_t>(nf));
  std::vector<int32_t> corners;
  for (int64_t i = 0; i < nf; ++i) {
    const TextLine& l = lines[next + static_cast<std::size_t>(nv + i)];
    const int64_t n = parse_count(path, l, 0, "face corner count");
    if (n < 3)
      fail(ErrorCode::InvalidData, "{}:{}: face has {} corners (need at least 3)", path.string(),
           l.number, n);
    if (static_cast<uint64_t>(n) > l.fields.size() - 1)  // before allocating for a bogus count
      fail(ErrorCode::InvalidData, "{}:{}: face declares {} corners but lists {}", path.string(),
           l.number, n, l.fields.size() - 1);
    corners.resize(static_cast<std::size_t>(n));
    for (int64_t c = 0; c < n; ++c) {
      const int64_t index = parse_count(path, l, static_cast<std::size_t>(c + 1), "vertex index");
      if (index >= nv)
        fail(ErrorCode::InvalidData, "{}:{}: vertex index {} outside [0, {})", path.string(),
             l.number, index, nv);
      corners[static_cast<std::size_t>(c)] = static_cast<int32_t>(index);
    }
    for (std::size_t c = 1; c + 1 < corners.size(); ++c)
      mesh.triangles.push_back({corners[0], corners[c], corners[c + 1]});
  }
  return mesh;
}

}  // namespace hivox

#include "hivox/io/ply.h"

#include <algorithm>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "hivox/core/error.h"
#include "hivox/io/atomic_file.h"

namespace hivox {

namespace {

// ---- writing ---------------------------------------------------------------------------------

template <typename T>
void put_le(std::vector<char>& buf, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  if constexpr (std::endian::native == std::endian::big) std::reverse(bytes, bytes + sizeof(T));
  buf.insert(buf.end(), bytes, bytes + sizeof(T));
}

// ---- reading ---------------------------------------------------------------------------------

enum class PlyFormat { Ascii, BinaryLittleEndian, BinaryBigEndian };
enum class PlyType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::Float32;  ///< value type (item type of a list)
  bool is_list = false;
  PlyType count_type = PlyType::UInt8;
};

struct PlyElement {
  std::string name;
  int64_t count = 0;
  std::vector<PlyProperty> properties;
  int find(const std::string& n) const {
    for (std::size_t i = 0; i < properties.size(); ++i)
      if (properties[i].name == n) return static_cast<int>(i);
    return -1;
  }
};

bool parse_type(const std::string& s, PlyType* t) {
  static const struct {
    const char* name;
    PlyType type;
  } kTypes[] = {
      {"char", PlyType::Int8},      {"int8", PlyType::Int8},       {"uchar", PlyType::UInt8},
      {"uint8", PlyType::UInt8},    {"short", PlyType::Int16},     {"int16", PlyType::Int16},
      {"ushort", PlyType::UInt16},  {"uint16", PlyType::UInt16},   {"int", PlyType::Int32},
      {"int32", PlyType::Int32},    {"uint", PlyType::UInt32},     {"uint32", PlyType::UInt32},
      {"float", PlyType::Float32},  {"float32", PlyType::Float32}, {"double", PlyType::Float64},
      {"float64", PlyType::Float64}};
  for (const auto& k : kTypes)
    if (s == k.name) {
      *t = k.type;
      return true;
    }
  return false;
}

int type_size(PlyType t) {
  switch (t) {
    case PlyType::Int8:
    case PlyType::UInt8:
      return 1;
    case PlyType::Int16:
    case PlyType::UInt16:
      return 2;
    case PlyType::Int32:
    case PlyType::UInt32:
    case PlyType::Float32:
      return 4;
    case PlyType::Float64:
      return 8;
  }
  return 0;
}

bool is_float(PlyType t) {
  return t == PlyType::Float32 || t == PlyType::Float64;
}

/// Reads values one at a time from the body of a PLY file, in its format.
class PlyBody {
 public:
  PlyBody(const std::string& path, const std::string& data, std::size_t pos, PlyFormat format)
      : path_(path), data_(data), pos_(pos), format_(format) {}

  /// The most values of type `t` that the rest of the file can hold (an ascii value takes at
  /// least a separator and a digit): bounds a list's length before allocating for it.
  double values_left(PlyType t) const {
    const double left = static_cast<double>(data_.size() - pos_);
    return format_ == PlyFormat::Ascii ? left / 2.0 : left / static_cast<double>(type_size(t));
  }

  /// Sets what is being read, for error messages.
  void set_context(const std::string& element, int64_t index) {
    element_ = &element;
    index_ = index;
  }

  double read(PlyType t) { return format_ == PlyFormat::Ascii ? read_ascii(t) : read_binary(t); }

 private:
  double read_binary(PlyType t) {
    const std::size_t n = static_cast<std::size_t>(type_size(t));
    if (pos_ + n > data_.size())
      fail(ErrorCode::InvalidData, "{}: file ends inside {} {} (truncated?)", path_, *element_,
           index_);
    unsigned char b[8];
    std::memcpy(b, data_.data() + pos_, n);
    pos_ += n;
    const bool swap =
        (format_ == PlyFormat::BinaryBigEndian) != (std::endian::native == std::endian::big);
    if (swap) std::reverse(b, b + n);
    switch (t) {
      case PlyType::Int8:
        return static_cast<double>(static_cast<int8_t>(b[0]));
      case PlyType::UInt8:
        return static_cast<double>(b[0]);
      case PlyType::Int16:
        return static_cast<double>(load<int16_t>(b));
      case PlyType::UInt16:
        return static_cast<double>(load<uint16_t>(b));
      case PlyType::Int32:
        return static_cast<double>(load<int32_t>(b));
      case PlyType::UInt32:
        return static_cast<double>(load<uint32_t>(b));
      case PlyType::Float32:
        return static_cast<double>(load<float>(b));
      case PlyType::Float64:
        return load<double>(b);
    }
    return 0.0;
  }

  template <typename T>
  static T load(const unsigned char* b) {
    T v;
    std::memcpy(&v, b, sizeof(T));
    return v;
  }

  double read_ascii(PlyType t) {
    while (pos_ < data_.size() && std::isspace(static_cast<unsigned char>(data_[pos_]))) ++pos_;
    if (pos_ >= data_.size())
      fail(ErrorCode::InvalidData, "{}: file ends inside {} {} (truncated?)", path_, *element_,
           index_);
    std::size_t end = pos_;
    while (end < data_.size() && !std::isspace(static_cast<unsigned char>(data_[end]))) ++end;
    const char* first = data_.data() + pos_;
    const char* last = data_.data() + end;
    double v = 0;
    std::from_chars_result r;
    if (is_float(t)) {
      r = std::from_chars(first, last, v);
    } else {
      long long i = 0;
      r = std::from_chars(first, last, i);
      v = static_cast<double>(i);
    }
    if (r.ec != std::errc() || r.ptr != last)
      fail(ErrorCode::InvalidData, "{}: {} {}: '{}' is not a valid number", path_, *element_,
           index_, std::string(first, last));
    pos_ = end;
    return v;
  }

  const std::string& path_;
  const std::string& data_;
  std::size_t pos_;
  PlyFormat format_;
  const std::string* element_ = nullptr;
  int64_t index_ = 0;
};

/// A byte from a value clamped to [0, 255]; NaN (float properties can hold it) is 0.
uint8_t to_byte(double v) {
  return std::isnan(v) ? 0 : static_cast<uint8_t>(std::clamp(std::round(v), 0.0, 255.0));
}

uint8_t to_channel(double v, PlyType t) {
  return to_byte(is_float(t) ? v * 255.0 : v);
}

}  // namespace

void write_ply(const std::filesystem::path& path, const TriangleMesh& mesh) {
  mesh.validate_for_writing(path.string());
  const bool normals = !mesh.normals_w.empty(), colors = !mesh.colors.empty();
  const bool levels = !mesh.levels.empty();
  std::string header = "ply\nformat binary_little_endian 1.0\ncomment written by hivox\n";
  header += "element vertex " + std::to_string(mesh.vertex_count()) + "\n";
  header += "property float x\nproperty float y\nproperty float z\n";
  if (normals) header += "property float nx\nproperty float ny\nproperty float nz\n";
  if (colors) header += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  if (levels) header += "property uchar level\n";
  header += "element face " + std::to_string(mesh.triangle_count()) + "\n";
  header += "property list uchar int vertex_indices\nend_header\n";

  AtomicFile file(path);
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(file.temp_path().c_str(), "wb"),
                                                    &std::fclose);
  if (!f) fail(ErrorCode::Io, "{}: cannot open for writing", path.string());
  // The body goes out in chunks of about 1 MiB.
  std::vector<char> buf;
  buf.reserve((1 << 20) + 64);
  bool ok = std::fwrite(header.data(), 1, header.size(), f.get()) == header.size();
  auto flush = [&](bool force) {
    if (!force && buf.size() < (1u << 20)) return;
    ok = ok && std::fwrite(buf.data(), 1, buf.size(), f.get()) == buf.size();
    buf.clear();
  };
  for (std::size_t i = 0; i < mesh.positions_w.size(); ++i) {
    const Vec3f& p = mesh.positions_w[i];
    put_le(buf, p.x);
    put_le(buf, p.y);
    put_le(buf, p.z);
    if (normals) {
      const Vec3f& n = mesh.normals_w[i];
      put_le(buf, n.x);
      put_le(buf, n.y);
      put_le(buf, n.z);
    }
    if (colors) {
      buf.push_back(static_cast<char>(mesh.colors[i].r));
      buf.push_back(static_cast<char>(mesh.colors[i].g));
      buf.push_back(static_cast<char>(mesh.colors[i].b));
    }
    if (levels) buf.push_back(static_cast<char>(mesh.levels[i]));
    flush(false);
  }
  for (const auto& t : mesh.triangles) {
    buf.push_back(3);
    for (const int32_t i : t) put_le(buf, i);
    flush(false);
  }
  flush(true);
  if (!ok || std::fclose(f.release()) != 0) fail(ErrorCode::Io, "{}: write failed", path.string());
  file.commit();
}

TriangleMesh read_ply(const std::filesystem::path& path_in) {
  const std::string path = path_in.string();
  const std::string data = read_whole_file(path_in);

  // Header: lines up to "end_header".
  std::size_t pos = 0;
  int line_number = 0;
  auto next_line = [&](std::string* line) {
    if (pos >= data.size()) return false;
    std::size_t end = data.find('\n', pos);
    if (end == std::string::npos) end = data.size();
    *line = data.substr(pos, end - pos);
    if (!line->empty() && line->back() == '\r') line->pop_back();
    pos = std::min(end + 1, data.size());
    ++line_number;
    return true;
  };
  std::string line;
  if (!next_line(&line) || line != "ply")
    fail(ErrorCode::InvalidData, "{}: not a PLY file (first line is not 'ply')", path);
  PlyFormat format = PlyFormat::Ascii;
  bool have_format = false, have_end = false;
  std::vector<PlyElement> elements;
  while (next_line(&line)) {
    std::istringstream in(line);
    std::string word;
    if (!(in >> word) || word == "comment" || word == "obj_info") continue;
    if (word == "end_header") {
      have_end = true;
      break;
    }
    if (word == "format") {
      std::string name, version;
      in >> name >> version;
      if (name == "ascii")
        format = PlyFormat::Ascii;
      else if (name == "binary_little_endian")
        format = PlyFormat::BinaryLittleEndian;
      else if (name == "binary_big_endian")
        format = PlyFormat::BinaryBigEndian;
      else
        fail(ErrorCode::InvalidData, "{}:{}: unknown PLY format '{}'", path, line_number, name);
      have_format = true;
    } else if (word == "element") {
      PlyElement e;
      if (!(in >> e.name >> e.count) || e.count < 0)
        fail(ErrorCode::InvalidData, "{}:{}: malformed element line '{}'", path, line_number, line);
      elements.push_back(std::move(e));
    } else if (word == "property") {
      if (elements.empty())
        fail(ErrorCode::InvalidData, "{}:{}: property before any element", path, line_number);
      PlyProperty p;
      std::string type;
      bool ok = static_cast<bool>(in >> type);
      if (ok && type == "list") {
        std::string count_type, item_type;
        p.is_list = true;
        ok = (in >> count_type >> item_type >> p.name) && parse_type(count_type, &p.count_type) &&
             !is_float(p.count_type) && parse_type(item_type, &p.type);
      } else {
        ok = ok && parse_type(type, &p.type) && static_cast<bool>(in >> p.name);
      }
      if (!ok)
        fail(ErrorCode::InvalidData, "{}:{}: malformed property line '{}'", path, line_number,
             line);
      elements.back().properties.push_back(std::move(p));
    } else {
      fail(ErrorCode::InvalidData, "{}:{}: unexpected header line '{}'", path, line_number, line);
    }
  }
  if (!have_format) fail(ErrorCode::InvalidData, "{}: PLY header has no format line", path);
  if (!have_end) fail(ErrorCode::InvalidData, "{}: PLY header has no end_header", path);

  // Element counts must fit in the file (guards against allocating for a bogus header): each
  // property takes at least its binary size, or one character plus a separator in ASCII.
  double min_bytes = 0;
  for (const PlyElement& e : elements) {
    int per_element = 0;
    for (const PlyProperty& p : e.properties)
      per_element += format == PlyFormat::Ascii ? 2 : type_size(p.is_list ? p.count_type : p.type);
    min_bytes += static_cast<double>(e.count) * per_element;
  }
  if (min_bytes > static_cast<double>(data.size() - pos) + 1.0)
    fail(ErrorCode::InvalidData, "{}: header declares more elements than the file's {} bytes hold",
         path, data.size() - pos);

  TriangleMesh mesh;
  PlyBody body(path, data, pos, format);
  bool have_vertices = false;
  for (const PlyElement& e : elements) {
    const std::size_t np = e.properties.size();
    std::vector<double> values(np);
    if (e.name == "vertex") {
      if (have_vertices) fail(ErrorCode::InvalidData, "{}: two vertex elements", path);
      have_vertices = true;
      const int x = e.find("x"), y = e.find("y"), z = e.find("z");
      if (x < 0 || y < 0 || z < 0)
        fail(ErrorCode::InvalidData, "{}: vertex element lacks x, y or z", path);
      const int nx = e.find("nx"), ny = e.find("ny"), nz = e.find("nz");
      const bool normals = nx >= 0 && ny >= 0 && nz >= 0;
      int r = e.find("red"), g = e.find("green"), b = e.find("blue");
      if (r < 0 || g < 0 || b < 0)
        r = e.find("diffuse_red"), g = e.find("diffuse_green"), b = e.find("diffuse_blue");
      const bool colors = r >= 0 && g >= 0 && b >= 0;
      const int level = e.find("level");
      for (const int k : {x, y, z, nx, ny, nz, r, g, b, level})
        if (k >= 0 && e.properties[static_cast<std::size_t>(k)].is_list)
          fail(ErrorCode::InvalidData, "{}: vertex property '{}' is a list", path,
               e.properties[static_cast<std::size_t>(k)].name);
      const std::size_t n = static_cast<std::size_t>(e.count);
      mesh.positions_w.resize(n);
      if (normals) mesh.normals_w.resize(n);
      if (colors) mesh.colors.resize(n);
      if (level >= 0) mesh.levels.resize(n);
      for (std::size_t i = 0; i < n; ++i) {
        body.set_context(e.name, static_cast<int64_t>(i));
        for (std::size_t k = 0; k < np; ++k) {
          const PlyProperty& p = e.properties[k];
          if (p.is_list) {
            const double count = body.read(p.count_type);
            for (int64_t c = 0; c < static_cast<int64_t>(count); ++c) body.read(p.type);
            values[k] = 0;
          } else {
            values[k] = body.read(p.type);
          }
        }
        auto v = [&](int k) { return static_cast<float>(values[static_cast<std::size_t>(k)]); };
        mesh.positions_w[i] = {v(x), v(y), v(z)};
        if (normals) mesh.normals_w[i] = {v(nx), v(ny), v(nz)};
        if (colors) {
          auto ch = [&](int k) {
            return to_channel(values[static_cast<std::size_t>(k)],
                              e.properties[static_cast<std::size_t>(k)].type);
          };
          mesh.colors[i] = {ch(r), ch(g), ch(b)};
        }
        if (level >= 0) mesh.levels[i] = to_byte(values[static_cast<std::size_t>(level)]);
      }
    } else if (e.name == "face") {
      int list = e.find("vertex_indices");
      if (list < 0) list = e.find("vertex_index");
      if (list < 0 || !e.properties[static_cast<std::size_t>(list)].is_list)
        fail(ErrorCode::InvalidData, "{}: face element has no vertex_indices list", path);
      std::vector<int64_t> corners;
      mesh.triangles.reserve(mesh.triangles.size() + static_cast<std::size_t>(e.count));
      for (int64_t i = 0; i < e.count; ++i) {
        body.set_context(e.name, i);
        for (std::size_t k = 0; k < np; ++k) {
          const PlyProperty& p = e.properties[k];
          if (!p.is_list) {
            body.read(p.type);
            continue;
          }
          const double count = body.read(p.count_type);
          if (count < 0)
            fail(ErrorCode::InvalidData, "{}: face {} has a negative list length", path, i);
          if (static_cast<int>(k) != list) {
            for (int64_t c = 0; c < static_cast<int64_t>(count); ++c) body.read(p.type);
            continue;
          }
          if (count > body.values_left(p.type))
            fail(ErrorCode::InvalidData,
                 "{}: file ends inside face {}: it lists {} corners, more than the rest of the "
                 "file holds (truncated?)",
                 path, i, count);
          corners.resize(static_cast<std::size_t>(count));
          for (int64_t& c : corners) {
            // Checked as read: a float index (NaN, 1e30) must not reach the integer cast.
            const double index = body.read(p.type);
            if (!(index >= 0.0 && index < static_cast<double>(mesh.positions_w.size())) ||
                !have_vertices)
              fail(ErrorCode::InvalidData, "{}: face {} has vertex index {} outside [0, {})", path,
                   i, index, mesh.positions_w.size());
            c = static_cast<int64_t>(index);
          }
        }
        if (corners.size() < 3)
          fail(ErrorCode::InvalidData, "{}: face {} has {} corners (need at least 3)", path, i,
               corners.size());
        for (std::size_t c = 1; c + 1 < corners.size(); ++c)
          mesh.triangles.push_back({static_cast<int32_t>(corners[0]),
                                    static_cast<int32_t>(corners[c]),
                                    static_cast<int32_t>(corners[c + 1])});
      }
    } else {
      for (int64_t i = 0; i < e.count; ++i) {
        body.set_context(e.name, i);
        for (const PlyProperty& p : e.properties) {
          const int64_t count = p.is_list ? static_cast<int64_t>(body.read(p.count_type)) : 1;
          for (int64_t c = 0; c < count; ++c) body.read(p.type);
        }
      }
    }
  }
  if (!have_vertices) fail(ErrorCode::InvalidData, "{}: PLY file has no vertex element", path);
  return mesh;
}

}  // namespace hivox

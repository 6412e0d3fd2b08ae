#include "hivox/io/npz.h"

#include <zip.h>

#include <cstdint>
#include <cstring>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "core/parallel.h"
#include "hivox/core/error.h"
#include "hivox/io/atomic_file.h"
#include "hivox/map/stored_map.h"

namespace hivox {

namespace {

/// One `.npy` file (format 1.0): magic, header dict padded to 64 bytes, little-endian C-order
/// data.
struct NpyArray {
  std::string name;
  std::vector<uint8_t> bytes;

  NpyArray(std::string array_name, const std::string& descr, const std::vector<int64_t>& shape,
           std::size_t data_bytes)
      : name(std::move(array_name) + ".npy") {
    std::string dims;
    for (const int64_t d : shape) dims += fmt::format("{}, ", d);
    if (shape.size() > 1) dims.resize(dims.size() - 2);  // "(N, 3)"; a 1-d shape keeps "(N,)"
    if (shape.size() == 1) dims.resize(dims.size() - 1);
    std::string header =
        fmt::format("{{'descr': '{}', 'fortran_order': False, 'shape': ({}), }}", descr, dims);
    const std::size_t total = 10 + header.size() + 1;
    header.append((64 - total % 64) % 64, ' ');
    header += '\n';
    bytes.reserve(10 + header.size() + data_bytes);
    const char magic[] = "\x93NUMPY\x01\x00";
    bytes.insert(bytes.end(), magic, magic + 8);
    const auto len = static_cast<uint16_t>(header.size());
    bytes.push_back(static_cast<uint8_t>(len & 0xff));
    bytes.push_back(static_cast<uint8_t>(len >> 8));
    bytes.insert(bytes.end(), header.begin(), header.end());
    bytes.resize(bytes.size() + data_bytes);
  }
  uint8_t* data() { return bytes.data() + (bytes.size() - data_size_); }
  void set_data_size(std::size_t n) { data_size_ = n; }

 private:
  std::size_t data_size_ = 0;
};

NpyArray make_array(const std::string& name, const std::string& descr,
                    const std::vector<int64_t>& shape, std::size_t element_bytes) {
  std::size_t n = element_bytes;
  for (const int64_t d : shape) n *= static_cast<std::size_t>(d);
  NpyArray a(name, descr, shape, n);
  a.set_data_size(n);
  return a;
}

}  // namespace

void write_map_npz(const std::filesystem::path& path, const VoxelBlockMap& map) {
  const MapParams& p = map.params();
  std::vector<NpyArray> arrays;
  {
    NpyArray sizes = make_array("voxel_size_m", "<f4", {p.levels}, 4);
    for (int l = 0; l < p.levels; ++l) {
      const float s = p.voxel_size_at(l);
      std::memcpy(sizes.data() + 4 * l, &s, 4);
    }
    arrays.push_back(std::move(sizes));
    NpyArray mu = make_array("truncation_m", "<f4", {}, 4);
    std::memcpy(mu.data(), &p.truncation_m, 4);
    arrays.push_back(std::move(mu));
  }
  for (int l = 0; l < p.levels; ++l) {
    const std::vector<BlockRef> blocks = sorted_blocks(map, l);
    const auto n = static_cast<int64_t>(blocks.size());
    NpyArray coords = make_array(fmt::format("level{}_coords", l), "<i4", {n, 3}, 4);
    NpyArray tsdf = make_array(fmt::format("level{}_tsdf", l), "<f4", {n, 8, 8, 8}, 4);
    NpyArray weight = make_array(fmt::format("level{}_weight", l), "<u2", {n, 8, 8, 8}, 2);
    std::optional<NpyArray> color;
    if (p.store_color)
      color = make_array(fmt::format("level{}_color", l), "|u1", {n, 8, 8, 8, 3}, 1);
    auto* c = reinterpret_cast<int32_t*>(coords.data());
    auto* t = reinterpret_cast<float*>(tsdf.data());
    auto* w = reinterpret_cast<uint16_t*>(weight.data());
    uint8_t* rgb = color ? color->data() : nullptr;
    const float mu = p.truncation_m;
    parallel_for(n, [&](int64_t i) {
      const BlockRef& b = blocks[static_cast<std::size_t>(i)];
      const int32_t xyz[3] = {b.pos.x, b.pos.y, b.pos.z};
      std::memcpy(c + 3 * i, xyz, sizeof xyz);
      const TsdfVoxel* v = map.block_tsdf(b.ptr);
      for (int k = 0; k < kBlockVoxels; ++k) {
        t[i * kBlockVoxels + k] = tsdf_to_float(v[k].tsdf) * mu;
        w[i * kBlockVoxels + k] = v[k].weight;
      }
      if (rgb != nullptr) {
        const ColorVoxel* cv = map.block_color(b.ptr);
        for (int k = 0; k < kBlockVoxels; ++k) {
          uint8_t* o = rgb + 3 * (i * kBlockVoxels + k);
          o[0] = cv[k].r;
          o[1] = cv[k].g;
          o[2] = cv[k].b;
        }
      }
    });
    arrays.push_back(std::move(coords));
    arrays.push_back(std::move(tsdf));
    arrays.push_back(std::move(weight));
    if (color) arrays.push_back(std::move(*color));
  }

  AtomicFile file(path);
  int err = 0;
  zip_t* zip = zip_open(file.temp_path().c_str(), ZIP_CREATE | ZIP_TRUNCATE, &err);
  if (zip == nullptr) fail(ErrorCode::Io, "{}: cannot open for writing", path.string());
  for (NpyArray& a : arrays) {
    zip_source_t* src = zip_source_buffer(zip, a.bytes.data(), a.bytes.size(), 0);
    const zip_int64_t index =
        src == nullptr ? -1 : zip_file_add(zip, a.name.c_str(), src, ZIP_FL_OVERWRITE);
    if (index < 0) {
      const std::string why = zip_strerror(zip);
      if (src != nullptr) zip_source_free(src);
      zip_discard(zip);
      fail(ErrorCode::Io, "{}: cannot add {}: {}", path.string(), a.name, why);
    }
    zip_set_file_compression(zip, static_cast<zip_uint64_t>(index), ZIP_CM_STORE, 0);
  }
  if (zip_close(zip) != 0) {
    const std::string why = zip_strerror(zip);
    zip_discard(zip);
    fail(ErrorCode::Io, "{}: write failed: {}", path.string(), why);
  }
  file.commit();
}

}  // namespace hivox

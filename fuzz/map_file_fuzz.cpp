// Fuzz target: map files (.hvx). The checksum would stop almost every mutated input at the door,
// so the target recomputes it over the mutated bytes first: the checks behind it (header fields,
// chunk table, decompression, the hierarchy of the blocks) see the damage. A map that loads must
// be consistent, and saving it again must load to the same counts.

#include <cstring>
#include <vector>

#define XXH_INLINE_ALL
#include <xxhash.h>

#include "fuzz_support.h"
#include "hivox/io/map_file.h"
#include "hivox/mesh/extract_mesh.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace hivox;
  std::vector<uint8_t> bytes(data, data + size);
  if (bytes.size() >= 16) {  // [checksum of everything before it][end marker]
    const uint64_t sum = XXH3_64bits(bytes.data(), bytes.size() - 16);
    std::memcpy(bytes.data() + bytes.size() - 16, &sum, 8);
  }
  const std::filesystem::path path = fuzz::input_file("map.hvx", bytes.data(), bytes.size());
  fuzz::expect_result_or_clear_error(path.string(), [&] {
    MapParams small;  // capacities kept small: a fuzzed count must not reserve gigabytes
    small.max_blocks = 4096;
    small.buckets_per_level = 1024;
    small.excess_per_level = 4096;
    const LoadedMap loaded = read_map_file(path, small);
    const TriangleMesh mesh = extract_mesh(*loaded.map);
    mesh.validate();
    const std::filesystem::path copy = fuzz::scratch_dir() / "map-copy.hvx";
    write_map_file(copy, *loaded.map, loaded.info.fusion, loaded.info.session);
    const LoadedMap again = read_map_file(copy, small);
    if (again.map->blocks_per_level() != loaded.map->blocks_per_level())
      fuzz::finding("a map file written and read back changed its block counts");
  });
  return 0;
}

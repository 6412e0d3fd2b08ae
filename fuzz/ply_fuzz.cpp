// Fuzz target: PLY meshes (ascii and both binary byte orders; `eval mesh` and tools read them).
// A mesh that reads must be consistent and survive being written and read back.

#include "fuzz_support.h"
#include "hivox/io/ply.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace hivox;
  const std::filesystem::path path = fuzz::input_file("mesh.ply", data, size);
  fuzz::expect_result_or_clear_error(path.string(), [&] {
    const TriangleMesh mesh = read_ply(path);
    mesh.validate();
    const std::filesystem::path copy = fuzz::scratch_dir() / "mesh-copy.ply";
    write_ply(copy, mesh);
    const TriangleMesh again = read_ply(copy);
    if (again.vertex_count() != mesh.vertex_count() ||
        again.triangle_count() != mesh.triangle_count())
      fuzz::finding("a PLY written and read back changed its vertex or triangle count");
  });
  return 0;
}

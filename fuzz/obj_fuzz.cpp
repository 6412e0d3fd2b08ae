// Fuzz target: OBJ meshes (reference meshes of `eval mesh`, `hivox view`). A mesh that reads must
// be consistent.

#include "fuzz_support.h"
#include "hivox/io/obj.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace hivox;
  const std::filesystem::path path = fuzz::input_file("mesh.obj", data, size);
  fuzz::expect_result_or_clear_error(path.string(), [&] { read_obj(path).validate(); });
  return 0;
}

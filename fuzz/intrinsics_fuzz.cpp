// Fuzz target: intrinsics.json. A file that reads must also survive being written and read
// back with the same image size.

#include "fuzz_support.h"
#include "hivox/io/intrinsics_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace hivox;
  const std::filesystem::path path = fuzz::input_file("intrinsics.json", data, size);
  fuzz::expect_result_or_clear_error(path.string(), [&] {
    const IntrinsicsFile read = read_intrinsics_json(path);
    const std::filesystem::path copy = fuzz::scratch_dir() / "intrinsics-copy.json";
    write_intrinsics_json(copy, read);
    const IntrinsicsFile again = read_intrinsics_json(copy);
    if (again.camera.width != read.camera.width || again.camera.height != read.camera.height)
      fuzz::finding("intrinsics written and read back changed the image size");
  });
  return 0;
}

// Fuzz target: image files (PNG, JPEG, PGM/PPM, told apart by their first bytes), read both as
// 16-bit depth and as colour, as a dataset's frames are.

#include "fuzz_support.h"
#include "hivox/io/image_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace hivox;
  const std::filesystem::path path = fuzz::input_file("image", data, size);
  fuzz::expect_result_or_clear_error(path.string(), [&] {
    const Image<uint16_t> raw = read_depth16(path);
    (void)depth_to_metres(raw, 5000.0);
  });
  fuzz::expect_result_or_clear_error(path.string(), [&] { (void)read_color(path); });
  return 0;
}

// Fuzz target: `synthetic:NAME?KEY=VALUE&...` specs. A spec either parses into parameters that
// validate, or is an error naming the spec's bad key or value (so no file name is required).

#include <string>

#include "fuzz_support.h"
#include "hivox/synth/synthetic_dataset.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace hivox;
  const std::string spec = "synthetic:" + std::string(reinterpret_cast<const char*>(data), size);
  fuzz::scratch_dir();  // quiets the log
  fuzz::expect_result_or_clear_error("", [&] { parse_synthetic_spec(spec).validate(); });
  return 0;
}

// Runs a fuzz target's entry point on saved inputs, without libFuzzer: how the seed corpora and
// every input a fuzzer once failed on (regressions/) are checked by the ordinary test suite and
// its sanitizer build. Arguments are files or folders of files.

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size);

int main(int argc, char** argv) {
  namespace fs = std::filesystem;
  std::vector<fs::path> inputs;
  for (int i = 1; i < argc; ++i) {
    const fs::path arg(argv[i]);
    std::error_code ec;
    if (fs::is_directory(arg, ec)) {
      for (const fs::directory_entry& e : fs::directory_iterator(arg))
        if (e.is_regular_file()) inputs.push_back(e.path());
    } else if (fs::is_regular_file(arg, ec)) {
      inputs.push_back(arg);
    } else if (!fs::exists(arg, ec)) {
      continue;  // a target may have no regressions yet
    }
  }
  std::sort(inputs.begin(), inputs.end());
  hivox::fuzz::recording() = true;
  if (inputs.empty()) {
    std::fprintf(stderr, "replay: no inputs found in the given paths\n");
    return 1;
  }
  for (const fs::path& p : inputs) {
    std::ifstream in(p, std::ios::binary);
    const std::vector<char> bytes((std::istreambuf_iterator<char>(in)), {});
    hivox::fuzz::outcomes().clear();
    LLVMFuzzerTestOneInput(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size());
    std::fprintf(stderr, "replay: %s (%zu bytes):", p.c_str(), bytes.size());
    for (const std::string& o : hivox::fuzz::outcomes()) std::fprintf(stderr, " [%s]", o.c_str());
    std::fprintf(stderr, "\n");
  }
  std::fprintf(stderr, "replay: %zu inputs, all handled\n", inputs.size());
  return 0;
}

#pragma once
// What every fuzz target shares. hivox's readers take paths, so each input is written to a file
// in a scratch folder of this process first. A reader may return or throw `hivox::Error` whose
// message names the input; anything else (a crash, another exception, a sanitizer report, an
// error that does not say which file) is a finding.

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include <unistd.h>

#include "hivox/core/error.h"
#include "hivox/core/log.h"

namespace hivox::fuzz {

/// A folder of this process, made on first use and removed at exit.
inline const std::filesystem::path& scratch_dir() {
  static const std::filesystem::path dir = [] {
    log::set_level(log::Level::Off);  // readers' warnings would drown the fuzzer's output
    std::filesystem::path d =
        std::filesystem::temp_directory_path() / ("hivox-fuzz-" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(scratch_dir(), ec);
    });
    return d;
  }();
  return dir;
}

inline void write_bytes(const std::filesystem::path& path, const uint8_t* data, std::size_t size) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  if (!out) {
    std::fprintf(stderr, "fuzz: cannot write %s\n", path.c_str());
    std::abort();
  }
}

/// Writes the input to `scratch_dir() / name` and returns that path.
inline std::filesystem::path input_file(std::string_view name, const uint8_t* data,
                                        std::size_t size) {
  const std::filesystem::path path = scratch_dir() / std::string(name);
  write_bytes(path, data, size);
  return path;
}

/// Stops the run with `what` on stderr: libFuzzer keeps the input as a crash.
[[noreturn]] inline void finding(const std::string& what) {
  std::fprintf(stderr, "fuzz finding: %s\n", what.c_str());
  std::abort();
}

/// What each check of the last input gave ("read" or the error), kept only when the replay tool
/// asks (`recording() = true`), so that seeds can be seen to reach past the first check.
inline bool& recording() {
  static bool on = false;
  return on;
}
inline std::vector<std::string>& outcomes() {
  static std::vector<std::string> list;
  return list;
}

/// Runs `body`; a `hivox::Error` is a fine outcome when its message contains `must_name` (the
/// file or folder the user gave). Other exceptions propagate and end the run as findings.
template <typename Body>
void expect_result_or_clear_error(std::string_view must_name, Body&& body) {
  try {
    body();
    if (recording()) outcomes().push_back("read");
  } catch (const Error& e) {
    if (recording()) outcomes().push_back(std::string("error: ") + e.what());
    if (std::string_view(e.what()).find(must_name) == std::string_view::npos)
      finding("the error does not name '" + std::string(must_name) + "': " + e.what());
  }
}

}  // namespace hivox::fuzz

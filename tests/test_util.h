#pragma once
// Helpers shared by the tests: a fresh temporary directory per test and the real-data folder.

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>

#include "hivox/core/error.h"

namespace hivox::test {

/// The error a call throws (code and message); records a test failure when it throws none.
template <typename F>
Error error_of(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e;
  }
  ADD_FAILURE() << "expected an hivox::Error, none was thrown";
  return Error(ErrorCode::Cuda, "(no error thrown)");
}

/// The message of the error a call throws; records a test failure when it throws none.
template <typename F>
std::string message_of(F&& f) {
  return error_of(std::forward<F>(f)).what();
}

/// The bytes of the file at `path` (empty where it cannot be read).
inline std::string file_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

/// The shared real-data folder ($HIVOX_DATA_DIR, else ../shared/data beside the project), or an
/// empty path when it is absent.
inline std::filesystem::path data_dir() {
  if (const char* env = std::getenv("HIVOX_DATA_DIR")) return env;
  std::filesystem::path p = HIVOX_TEST_DATA_DIR;
  return std::filesystem::is_directory(p) ? p : std::filesystem::path{};
}

/// Path of a real data set, or skips the test with a clear message when it is missing.
#define HIVOX_REQUIRE_DATASET(var, name)                                                      \
  const std::filesystem::path var = ::hivox::test::data_dir() / (name);                       \
  if (::hivox::test::data_dir().empty() || !std::filesystem::is_directory(var))               \
  GTEST_SKIP() << "real data set '" << (name) << "' not found (looked in ../shared/data and " \
               << "$HIVOX_DATA_DIR); skipping"

/// A temporary directory removed at the end of the test.
class TempDir {
 public:
  TempDir() {
    std::random_device rd;
    path_ = std::filesystem::temp_directory_path() /
            ("hivox_test_" + std::to_string(rd()) + "_" + std::to_string(rd()));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

inline void write_text(const std::filesystem::path& path, const std::string& text) {
  std::filesystem::create_directories(path.parent_path());
  std::ofstream(path) << text;
}

}  // namespace hivox::test

#pragma once
/// @file
/// The one exception type of hivox. Thrown at API boundaries, never from kernels; the library
/// never calls exit or abort.

#include <stdexcept>
#include <string>
#include <string_view>

#include <fmt/format.h>

namespace hivox {

enum class ErrorCode {
  InvalidArgument,  ///< a parameter or argument is out of its legal range
  Io,               ///< a file or directory is missing, unreadable or unwritable
  InvalidData,      ///< a file exists but its content is malformed (bad line, wrong bit depth)
  OutOfCapacity,    ///< a fixed capacity (hash table, block pool) cannot hold what is asked
  Unsupported,      ///< a valid request that this build or format cannot serve
  Cuda,             ///< a CUDA runtime call failed
};

std::string_view to_string(ErrorCode code);

class Error : public std::runtime_error {
 public:
  Error(ErrorCode code, const std::string& message) : std::runtime_error(message), code_(code) {}
  ErrorCode code() const { return code_; }

 private:
  ErrorCode code_;
};

/// Throws `Error(code, fmt::format(...))`. One line that names the file or parameter.
template <typename... Args>
[[noreturn]] void fail(ErrorCode code, fmt::format_string<Args...> format, Args&&... args) {
  throw Error(code, fmt::format(format, std::forward<Args>(args)...));
}

}  // namespace hivox

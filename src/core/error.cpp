#include "hivox/core/error.h"

namespace hivox {

std::string_view to_string(ErrorCode code) {
  switch (code) {
    case ErrorCode::InvalidArgument:
      return "invalid argument";
    case ErrorCode::Io:
      return "I/O error";
    case ErrorCode::InvalidData:
      return "invalid data";
    case ErrorCode::OutOfCapacity:
      return "out of capacity";
    case ErrorCode::Unsupported:
      return "unsupported";
    case ErrorCode::Cuda:
      return "CUDA error";
  }
  return "unknown error";
}

}  // namespace hivox

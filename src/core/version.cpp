#include "hivox/core/version.h"

namespace hivox {

std::string_view library_version() {
  return HIVOX_VERSION;  // defined for this file alone by src/CMakeLists.txt
}

}  // namespace hivox

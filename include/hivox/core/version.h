#pragma once
/// @file
/// The library's version (the project's, as CMake knows it), e.g. for files that record which
/// hivox wrote them.

#include <string_view>

namespace hivox {

/// "MAJOR.MINOR.PATCH".
std::string_view library_version();

}  // namespace hivox

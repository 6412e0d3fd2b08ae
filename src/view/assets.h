#pragma once
// The viewer pages' own files (web/) and three.js (Debian's libjs-three), built into the
// program by src/view/assets.cpp.in so that an installed `hivox` serves them with no other file.

#include <optional>
#include <string_view>

namespace hivox::view {

/// The file `name` (e.g. "live.html", "three.min.js"), or nothing for a name not built in.
std::optional<std::string_view> static_asset(std::string_view name);

}  // namespace hivox::view

#pragma once
// Small helpers the view's JSON and query handling share.

#include <charconv>
#include <cstddef>
#include <string>
#include <string_view>

#include <fmt/format.h>

#include "hivox/core/error.h"
#include "hivox/core/image.h"

namespace hivox::view {

/// "#rrggbb".
inline std::string hex_color(Rgb8 c) {
  return fmt::format("#{:02x}{:02x}{:02x}", c.r, c.g, c.b);
}

/// A non-negative count from a query parameter; `Error(InvalidArgument)` (a 400 reply) otherwise.
inline std::size_t parse_count(std::string_view text, std::string_view name) {
  std::size_t value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || ec != std::errc() || end != text.data() + text.size())
    fail(ErrorCode::InvalidArgument, "query parameter '{}' must be a count, got '{}'", name, text);
  return value;
}

}  // namespace hivox::view

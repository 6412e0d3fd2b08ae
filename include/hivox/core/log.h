#pragma once
/// @file
/// Logging for library and tools (stderr). Kernels never log: they count, and drivers report.

#include <string>
#include <string_view>

#include <fmt/format.h>

namespace hivox::log {

enum class Level { Debug, Info, Warn, Error, Off };

void set_level(Level level);
Level level();
void write(Level level, std::string_view message);
/// Writes `message` the first time `key` is seen in this process; later calls are silent.
/// Used for "capacity exceeded, raise --max-blocks" style warnings that must not flood.
void write_once(Level level, std::string_view key, std::string_view message);

template <typename... Args>
void debug(fmt::format_string<Args...> f, Args&&... args) {
  if (level() <= Level::Debug) write(Level::Debug, fmt::format(f, std::forward<Args>(args)...));
}
template <typename... Args>
void info(fmt::format_string<Args...> f, Args&&... args) {
  if (level() <= Level::Info) write(Level::Info, fmt::format(f, std::forward<Args>(args)...));
}
template <typename... Args>
void warn(fmt::format_string<Args...> f, Args&&... args) {
  if (level() <= Level::Warn) write(Level::Warn, fmt::format(f, std::forward<Args>(args)...));
}
template <typename... Args>
void error(fmt::format_string<Args...> f, Args&&... args) {
  if (level() <= Level::Error) write(Level::Error, fmt::format(f, std::forward<Args>(args)...));
}
template <typename... Args>
void warn_once(std::string_view key, fmt::format_string<Args...> f, Args&&... args) {
  write_once(Level::Warn, key, fmt::format(f, std::forward<Args>(args)...));
}

}  // namespace hivox::log

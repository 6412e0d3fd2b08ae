#pragma once
/// @file
/// Reading whitespace-separated text lists (TUM lists, calibration files) with line numbers, so
/// that a malformed line in a long list is reported as `FILE:LINE: problem`.

#include <filesystem>
#include <string>
#include <vector>

namespace hivox {

struct TextLine {
  int number = 0;                   ///< 1-based line number in the file
  std::vector<std::string> fields;  ///< whitespace-separated tokens
};

/// Non-empty, non-comment (`#`) lines of a text file. Throws `Error(Io)` naming the file when it
/// is missing or unreadable.
std::vector<TextLine> read_text_lines(const std::filesystem::path& path);

/// Parses `line.fields[i]` as a finite double or throws `Error(InvalidData)` naming
/// `path:line` and `what`.
double parse_double(const std::filesystem::path& path, const TextLine& line, std::size_t i,
                    const char* what);

}  // namespace hivox

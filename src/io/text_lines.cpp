#include "hivox/io/text_lines.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

#include "hivox/core/error.h"

namespace hivox {

std::vector<TextLine> read_text_lines(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    fail(ErrorCode::Io, "{}: file does not exist", path.string());
  std::ifstream in(path);
  if (!in) fail(ErrorCode::Io, "{}: cannot open for reading", path.string());
  std::vector<TextLine> lines;
  std::string text;
  int number = 0;
  while (std::getline(in, text)) {
    ++number;
    const auto first = text.find_first_not_of(" \t\r");
    if (first == std::string::npos || text[first] == '#') continue;
    TextLine line;
    line.number = number;
    std::istringstream fields(text);
    for (std::string f; fields >> f;) line.fields.push_back(f);
    if (line.fields.empty()) continue;  // other whitespace only (a vertical tab, a form feed)
    lines.push_back(std::move(line));
  }
  if (in.bad()) fail(ErrorCode::Io, "{}: read error", path.string());
  return lines;
}

double parse_double(const std::filesystem::path& path, const TextLine& line, std::size_t i,
                    const char* what) {
  if (i >= line.fields.size())
    fail(ErrorCode::InvalidData, "{}:{}: missing {} (field {})", path.string(), line.number, what,
         i + 1);
  const std::string& s = line.fields[i];
  double value = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
  if (ec != std::errc() || end != s.data() + s.size() || !std::isfinite(value))
    fail(ErrorCode::InvalidData, "{}:{}: {} '{}' is not a number", path.string(), line.number, what,
         s);
  return value;
}

}  // namespace hivox

// Fuzz target: whole dataset folders, as `hivox reconstruct DIR` opens them (TUM lists,
// associations and ground truth, InfiniTAM calib.txt, 7-Scenes frames and poses, intrinsics.json,
// the images they name). One input holds several files:
//
//   === rgb.txt
//   1.0 rgb/1.png
//   === depth/1.png
//   <bytes>
//
// Each `=== NAME` line starts a file (NAME relative, without `..`), which runs up to the next
// such line. The folder is opened, described, and its first frames are read.

#include <algorithm>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_support.h"
#include "hivox/io/dataset.h"

namespace {

namespace fs = std::filesystem;

constexpr std::string_view kMarker = "=== ";
constexpr std::size_t kMaxFiles = 32;
constexpr std::size_t kFramesRead = 3;

bool acceptable_name(std::string_view name) {
  if (name.empty() || name.size() > 80 || name.front() == '/') return false;
  for (char c : name)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-' ||
          c == '/'))
      return false;
  for (const fs::path& part : fs::path(name))
    if (part == ".." || part == ".") return false;
  return true;
}

/// Writes the files of `input` under `dir`; returns how many were written.
std::size_t unpack(std::string_view input, const fs::path& dir) {
  std::size_t written = 0, pos = 0;
  if (!input.starts_with(kMarker)) {
    pos = input.find(std::string("\n") + std::string(kMarker));
    if (pos == std::string_view::npos) return 0;
    ++pos;
  }
  while (pos < input.size() && written < kMaxFiles) {
    const std::size_t name_begin = pos + kMarker.size();
    const std::size_t name_end = input.find('\n', name_begin);
    if (name_end == std::string_view::npos) break;
    std::size_t next = input.find(std::string("\n") + std::string(kMarker), name_end);
    std::size_t content_end = next == std::string_view::npos ? input.size() : next;
    if (next == std::string_view::npos && content_end > name_end + 1 &&
        input[content_end - 1] == '\n')
      --content_end;  // the packer ends each file with a newline
    const std::string_view name = input.substr(name_begin, name_end - name_begin);
    const std::string_view content = input.substr(name_end + 1, content_end - name_end - 1);
    if (acceptable_name(name)) {
      const fs::path path = dir / std::string(name);
      std::error_code ec;
      fs::create_directories(path.parent_path(), ec);
      if (!ec && !fs::is_directory(path, ec)) {
        hivox::fuzz::write_bytes(path, reinterpret_cast<const uint8_t*>(content.data()),
                                 content.size());
        ++written;
      }
    }
    if (next == std::string_view::npos) break;
    pos = next + 1;
  }
  return written;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace hivox;
  const fs::path dir = fuzz::scratch_dir() / "dataset";
  std::error_code ec;
  fs::remove_all(dir, ec);
  fs::create_directories(dir);
  if (unpack(std::string_view(reinterpret_cast<const char*>(data), size), dir) == 0) return 0;
  fuzz::expect_result_or_clear_error(dir.string(), [&] {
    std::unique_ptr<DatasetReader> reader = open_dataset(dir.string(), DatasetParams{});
    (void)describe_dataset(*reader);
    for (std::size_t i = 0; i < std::min(reader->size(), kFramesRead); ++i) (void)reader->read(i);
  });
  return 0;
}

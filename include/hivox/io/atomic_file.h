#pragma once
/// @file
/// Files people keep are written whole or not at all: under a temporary name beside the final
/// path, renamed over it once complete. A reader (or a later run) sees the previous file or the
/// whole new one, never a part, whatever interrupts the writing.

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>

namespace hivox {

class AtomicFile {
 public:
  /// Chooses a temporary name beside `path` (same folder, so the rename is atomic).
  explicit AtomicFile(std::filesystem::path path);
  /// Removes the temporary file unless commit() ran.
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  /// Where to write (close the file before commit()).
  const std::filesystem::path& temp_path() const { return temp_; }
  const std::filesystem::path& path() const { return path_; }
  /// Renames the written temporary file to the final path, replacing what was there. Throws
  /// `Error(Io)` naming the final path when it cannot.
  void commit();

 private:
  std::filesystem::path path_, temp_;
  bool committed_ = false;
};

/// Writes `parts` one after the other as the file `path`, atomically (an AtomicFile). A file that
/// cannot be written is `Error(Io)` naming `path`.
void write_file_atomically(const std::filesystem::path& path,
                           std::span<const std::span<const uint8_t>> parts);
/// The same with one part: `content`.
void write_file_atomically(const std::filesystem::path& path, std::string_view content);

/// The whole content of the file `path`. A missing file, or one that cannot be read, is
/// `Error(Io)` naming it.
std::string read_whole_file(const std::filesystem::path& path);

}  // namespace hivox

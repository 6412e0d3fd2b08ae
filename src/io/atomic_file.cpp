#include "hivox/io/atomic_file.h"

#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <memory>
#include <string>
#include <system_error>

#include "hivox/core/error.h"

namespace hivox {

namespace fs = std::filesystem;

AtomicFile::AtomicFile(fs::path path) : path_(std::move(path)) {
  static std::atomic<unsigned> counter{0};
  temp_ = path_;
  temp_ += ".tmp-" + std::to_string(getpid()) + "-" + std::to_string(counter++);
}

AtomicFile::~AtomicFile() {
  if (committed_) return;
  std::error_code ec;
  fs::remove(temp_, ec);  // nothing to report: the write itself failed or was abandoned
}

void AtomicFile::commit() {
  std::error_code ec;
  fs::rename(temp_, path_, ec);
  if (ec)
    fail(ErrorCode::Io, "{}: cannot move the written file into place ({})", path_.string(),
         ec.message());
  committed_ = true;
}

void write_file_atomically(const fs::path& path, std::span<const std::span<const uint8_t>> parts) {
  AtomicFile file(path);
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(file.temp_path().c_str(), "wb"),
                                                    &std::fclose);
  if (!f) fail(ErrorCode::Io, "{}: cannot open for writing", path.string());
  bool ok = true;
  for (const std::span<const uint8_t> part : parts)
    ok = ok && std::fwrite(part.data(), 1, part.size(), f.get()) == part.size();
  if (!ok || std::fclose(f.release()) != 0)
    fail(ErrorCode::Io, "{}: write failed (disk full?)", path.string());
  file.commit();
}

void write_file_atomically(const fs::path& path, std::string_view content) {
  const std::span<const uint8_t> part(reinterpret_cast<const uint8_t*>(content.data()),
                                      content.size());
  write_file_atomically(path, std::span<const std::span<const uint8_t>>(&part, 1));
}

std::string read_whole_file(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) fail(ErrorCode::Io, "{}: file does not exist", path.string());
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) fail(ErrorCode::Io, "{}: cannot open for reading", path.string());
  // One read of the size the file has now; a file that grows meanwhile is read in pieces.
  std::string data(fs::file_size(path, ec), '\0');
  if (ec) data.clear();
  std::size_t have = std::fread(data.data(), 1, data.size(), f.get());
  data.resize(have);
  char piece[1 << 16];
  while ((have = std::fread(piece, 1, sizeof piece, f.get())) > 0) data.append(piece, have);
  if (std::ferror(f.get())) fail(ErrorCode::Io, "{}: read error", path.string());
  return data;
}

}  // namespace hivox

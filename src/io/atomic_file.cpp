#include "hivox/io/atomic_file.h"

#include <unistd.h>

#include <atomic>
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

}  // namespace hivox

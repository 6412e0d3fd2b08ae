#include "hivox/output/output_folder.h"

#include <unistd.h>

#include <string>
#include <system_error>

#include "hivox/core/error.h"

namespace hivox {

namespace fs = std::filesystem;

OutputFolder::OutputFolder(const fs::path& out, bool overwrite, const char* what) : out_(out) {
  if (out_.empty()) return;
  std::error_code ec;
  if (fs::exists(out_, ec)) {
    if (!fs::is_directory(out_, ec))
      fail(ErrorCode::Io, "{}: the output path exists and is not a folder", out_.string());
    if (!fs::is_empty(out_, ec) && !overwrite)
      fail(ErrorCode::InvalidArgument,
           "{}: the output folder holds files already (an earlier run?); pass {} to replace it "
           "as a whole, or choose another folder",
           out_.string(), what);
  }
  fs::path base = out_.lexically_normal();
  if (base.filename().empty()) base = base.parent_path();
  staging_ = base;
  staging_ += ".partial-" + std::to_string(getpid());
  fs::remove_all(staging_, ec);
  fs::create_directories(staging_, ec);
  if (ec)
    fail(ErrorCode::Io, "{}: cannot create the output folder ({})", staging_.string(),
         ec.message());
}

OutputFolder::~OutputFolder() {
  if (staging_.empty() || committed_) return;
  std::error_code ec;  // a failed run leaves nothing behind, and the old folder as it was
  fs::remove_all(staging_, ec);
}

void OutputFolder::commit() {
  if (staging_.empty()) return;
  std::error_code ec;
  fs::path old;
  if (fs::exists(out_, ec)) {
    old = staging_.parent_path() / (staging_.filename().string() + ".replaced");
    fs::rename(out_, old, ec);
    if (ec)
      fail(ErrorCode::Io, "{}: cannot move the old folder aside ({}); the results are in {}",
           out_.string(), ec.message(), staging_.string());
  }
  fs::rename(staging_, out_, ec);
  if (ec)
    fail(ErrorCode::Io, "{}: cannot move the results into place ({}); they are in {}",
         out_.string(), ec.message(), staging_.string());
  committed_ = true;
  if (!old.empty()) fs::remove_all(old, ec);
}

fs::path OutputFolder::final_path(const fs::path& written) const {
  const fs::path inside = written.lexically_relative(staging_);
  if (inside.empty() || *inside.begin() == "..") return written;  // not one of the folder's
  return out_ / inside;
}

}  // namespace hivox

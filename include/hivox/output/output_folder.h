#pragma once
/// @file
/// A folder of results written whole: the files go into `<out>.partial-<pid>` beside it, and the
/// folder is moved into place when everything is written, replacing an older `<out>` as a whole
/// when that is allowed. No reader (or later run) ever sees one run's files mixed with another's
/// or a folder half written.

#include <filesystem>

namespace hivox {

class OutputFolder {
 public:
  /// `out` empty: no folder (writes() is false). An `out` that holds files already is refused
  /// with `Error(InvalidArgument)` unless `overwrite`; `what` names the option that allows it in
  /// that message (e.g. "--overwrite").
  OutputFolder(const std::filesystem::path& out, bool overwrite, const char* what = "--overwrite");
  /// Removes the partial folder unless commit() ran (the old `out`, if any, stays as it was).
  ~OutputFolder();
  OutputFolder(const OutputFolder&) = delete;
  OutputFolder& operator=(const OutputFolder&) = delete;

  bool writes() const { return !out_.empty(); }
  /// Where files go until commit().
  const std::filesystem::path& dir() const { return staging_; }
  /// The final folder.
  const std::filesystem::path& out() const { return out_; }
  /// Moves the folder into place; an older `out` is moved aside first and removed after. Throws
  /// `Error(Io)` saying where the results are when it cannot.
  void commit();
  /// The final path of a file written into dir(); other paths are returned as they are.
  std::filesystem::path final_path(const std::filesystem::path& written) const;

 private:
  std::filesystem::path out_, staging_;
  bool committed_ = false;
};

}  // namespace hivox

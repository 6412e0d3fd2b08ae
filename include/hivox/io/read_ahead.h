#pragma once
/// @file
/// A dataset's frames read ahead on threads of their own, so that decoding the next frames (PNG,
/// lens distortion, a synthetic scene's rendering) overlaps the processing of this one: what a
/// run reads through (RunParams::read_threads), for loops of one's own too.

#include <condition_variable>
#include <cstddef>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

#include "hivox/core/dataset.h"

namespace hivox {

/// Reads frames [first, end) of `reader` ahead of the caller, at most `ahead` frames beyond the
/// last one taken, on `threads` threads (one where the reader does not read concurrently, see
/// DatasetReader::reads_concurrently); `ahead` 0: each frame is read when taken, on the
/// caller's thread. The reader is used only by this object while it lives. A frame that cannot
/// be read is not skipped: `next()` throws its error at its turn, and the frames after it come
/// as usual. One reading thread uses thread_count() threads for its parallel loops (as many as
/// the constructing thread), several one each. `ahead` and `threads` must lie in [0, 64]
/// (`Error(InvalidArgument)` names them).
class ReadAhead {
 public:
  /// The frames read ahead for `threads` threads unless said otherwise: two each.
  static int frames_for(int threads) { return 2 * threads; }

  ReadAhead(DatasetReader& reader, std::size_t first, std::size_t end, int ahead, int threads = 1);
  /// Stops reading (reads under way end first); frames read and not taken are dropped.
  ~ReadAhead();
  ReadAhead(const ReadAhead&) = delete;
  ReadAhead& operator=(const ReadAhead&) = delete;

  /// The next frame in order (first, first + 1, ...): waits until it is read, and throws what
  /// reading it threw (an `Error` naming the file). `Error(InvalidArgument)` past `end`.
  RgbdFrame next();
  /// The frames next() has still to give.
  std::size_t left() const { return end_ - next_; }

 private:
  struct Slot {
    bool ready = false;
    RgbdFrame frame;
    std::exception_ptr error;
  };
  void read_frames(int loop_threads);
  /// Ends the reading threads (reads under way first).
  void stop();

  DatasetReader& reader_;
  const std::size_t first_, end_;
  std::size_t next_;  ///< the frame next() returns (the caller's thread only)
  std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<Slot> slots_;  ///< frame i in slot (i - first) % ahead
  std::size_t claimed_;      ///< frames [first, claimed_) are read or being read
  std::size_t taken_;        ///< frames [first, taken_) were taken
  bool stop_ = false;
  std::vector<std::thread> threads_;  ///< last: they start once the rest is set
};

}  // namespace hivox

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
/// as usual. The reading threads use `threads` of the machine's cores: several one each, one
/// (`threads` > 1 where the dataset reads one frame at a time) that many for its parallel
/// loops, at most as many as the constructing thread's. While they read, the constructing
/// thread's parallel loops use the cores they leave (thread_count(), at least 1); its count is
/// restored when reading stops on that thread (the destructor, normally). `ahead` and `threads`
/// must lie in [0, 64] (`Error(InvalidArgument)` names them).
class ReadAhead {
 public:
  /// The frames read ahead for `threads` threads unless said otherwise: two each.
  static int frames_for(int threads) { return 2 * threads; }

  /// How the cores are shared while `frames` frames are read `ahead` (> 0) on `threads` threads,
  /// from a reader that reads `concurrently` or not, beside a caller whose parallel loops have
  /// `caller_threads` threads.
  struct Sharing {
    int readers = 0;         ///< reading threads
    int reader_threads = 0;  ///< each one's parallel loops (several readers: 1 each)
    int caller_threads = 0;  ///< the caller's parallel loops while they read (at least 1)
  };
  static Sharing sharing(bool concurrently, std::size_t frames, int ahead, int threads,
                         int caller_threads);

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
  std::thread::id owner_;  ///< the constructing thread, when its loops were given fewer threads
  int owner_threads_ = 0;  ///< its thread count before (0: unchanged)
  std::vector<std::thread> threads_;  ///< last: they start once the rest is set
};

}  // namespace hivox

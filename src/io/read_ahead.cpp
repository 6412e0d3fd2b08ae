#include "hivox/io/read_ahead.h"

#include <algorithm>
#include <system_error>
#include <utility>

#include "core/parallel.h"
#include "hivox/core/error.h"
#include "hivox/core/log.h"

namespace hivox {

ReadAhead::ReadAhead(DatasetReader& reader, std::size_t first, std::size_t end, int ahead,
                     int threads)
    : reader_(reader),
      first_(first),
      end_(end),
      next_(first),
      slots_(ahead > 0 ? static_cast<std::size_t>(ahead) : 0),
      claimed_(first),
      taken_(first) {
  if (ahead < 0 || ahead > 64 || threads < 0 || threads > 64)
    fail(ErrorCode::InvalidArgument,
         "reading ahead: {} frames on {} threads; both must be in [0, 64]", ahead, threads);
  if (slots_.empty() || first >= end) return;
  const int caller_threads = thread_count();
  const Sharing share =
      sharing(reader.reads_concurrently(), end - first, ahead, threads, caller_threads);
  const int loop_threads = share.reader_threads;
  threads_.reserve(static_cast<std::size_t>(share.readers));
  try {
    for (int t = 0; t < share.readers; ++t)
      threads_.emplace_back([this, loop_threads] { read_frames(loop_threads); });
  } catch (const std::system_error& e) {
    // No thread to be had: the frames are read in turn, as without reading ahead.
    log::warn_once("read_ahead.threads",
                   "reading ahead: cannot start a thread ({}); frames are read in turn", e.what());
    stop();  // no thread left: next() reads in turn
    return;
  }
  if (share.caller_threads < caller_threads) {
    owner_ = std::this_thread::get_id();
    owner_threads_ = caller_threads;
    detail::use_thread_count(share.caller_threads);
  }
}

ReadAhead::Sharing ReadAhead::sharing(bool concurrently, std::size_t frames, int ahead, int threads,
                                      int caller_threads) {
  Sharing s;
  s.readers = concurrently ? std::max(threads, 1) : 1;
  s.readers = static_cast<int>(std::min<std::size_t>(
      {static_cast<std::size_t>(s.readers), static_cast<std::size_t>(std::max(ahead, 0)), frames}));
  if (s.readers == 0) {  // nothing read ahead: the caller keeps its threads
    s.caller_threads = caller_threads;
    return s;
  }
  // The reading threads use `threads` of the cores (several one each, one all of them for its
  // parallel loops), the caller's loops the cores left. Cores asked for twice make OpenMP's
  // spinning teams wait on threads the system has descheduled: on a 16-core machine a GPU
  // loop's frame copy, with its 16 threads beside 8 readers, took 10 ms instead of 0.1.
  s.reader_threads = s.readers == 1 ? std::clamp(threads, 1, std::max(caller_threads, 1)) : 1;
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  s.caller_threads = std::max(1, std::min(caller_threads, cores - s.readers * s.reader_threads));
  return s;
}

ReadAhead::~ReadAhead() {
  stop();
}

void ReadAhead::stop() {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  changed_.notify_all();
  for (std::thread& t : threads_) t.join();
  threads_.clear();
  if (owner_threads_ > 0 && std::this_thread::get_id() == owner_) {
    detail::use_thread_count(owner_threads_);
    owner_threads_ = 0;
  }
}

void ReadAhead::read_frames(int loop_threads) {
  detail::use_thread_count(loop_threads);
  for (;;) {
    std::size_t i = 0;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      // Frame i may be read once the frame `ahead` before it (its slot's last) was taken.
      changed_.wait(lock,
                    [&] { return stop_ || claimed_ >= end_ || claimed_ < taken_ + slots_.size(); });
      if (stop_ || claimed_ >= end_) return;
      i = claimed_++;
    }
    Slot s;
    try {
      s.frame = reader_.read(i);
    } catch (...) {
      s.error = std::current_exception();
    }
    s.ready = true;
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      slots_[(i - first_) % slots_.size()] = std::move(s);
    }
    changed_.notify_all();
  }
}

RgbdFrame ReadAhead::next() {
  if (left() == 0)
    fail(ErrorCode::InvalidArgument, "reading ahead: frame {} is past the end ({})", next_, end_);
  const std::size_t i = next_++;
  if (threads_.empty()) return reader_.read(i);
  Slot s;
  {
    std::unique_lock<std::mutex> lock(mutex_);
    Slot& slot = slots_[(i - first_) % slots_.size()];
    changed_.wait(lock, [&] { return slot.ready; });
    s = std::move(slot);
    slot = Slot{};
    taken_ = i + 1;
  }
  changed_.notify_all();
  if (s.error) std::rethrow_exception(s.error);
  return std::move(s.frame);
}

}  // namespace hivox

// Frames read ahead on threads of their own (ReadAhead, what a run reads through): the same
// frames in order as reading them one by one, errors at their frame's turn, never more than the
// frames asked for ahead, several reads at once only where the dataset allows them, and an end
// that waits for nothing. A run reading ahead reconstructs exactly what a run reading each frame
// in turn does.

#include "hivox/io/read_ahead.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>

#include "hivox/core/error.h"
#include "hivox/core/threads.h"
#include "hivox/run/runner.h"
#include "hivox/synth/synthetic_dataset.h"
#include "run/small_run.h"
#include "test_util.h"

namespace hivox {
namespace {

/// Frames whose depth holds their index; records what was read, on which thread, and how many
/// reads ran at once (each takes `read_ms`). Frame `bad` throws an Error naming it, frame `odd` a
/// std::runtime_error.
class CountingReader : public DatasetReader {
 public:
  explicit CountingReader(std::size_t frames, bool concurrent = false, int read_ms = 0)
      : concurrent_(concurrent), read_ms_(read_ms) {
    info_.frame_count = frames;
    info_.source = "counting";
  }
  const DatasetInfo& info() const override { return info_; }
  bool reads_concurrently() const override { return concurrent_; }
  RgbdFrame read(std::size_t index) override {
    const int started = ++reads;
    most_ahead = std::max(most_ahead.load(), started - taken.load());
    if (std::this_thread::get_id() != caller) ++reads_elsewhere;
    loop_threads = thread_count();
    const int now = ++in_flight;
    most_at_once = std::max(most_at_once.load(), now);
    std::this_thread::sleep_for(std::chrono::milliseconds(read_ms_));
    --in_flight;
    if (index == bad) fail(ErrorCode::Io, "counting/frame{}.png: truncated", index);
    if (index == odd) throw std::runtime_error("not an hivox error");
    RgbdFrame f;
    f.index = index;
    f.timestamp_s = static_cast<double>(index);
    f.depth_m = DepthImage(4, 3, static_cast<float>(index));
    return f;
  }

  std::size_t bad = SIZE_MAX, odd = SIZE_MAX;
  std::thread::id caller = std::this_thread::get_id();
  std::atomic<int> reads{0}, taken{0}, most_ahead{0}, reads_elsewhere{0};
  std::atomic<int> in_flight{0}, most_at_once{0};
  std::atomic<int> loop_threads{0};  ///< thread_count() where the last frame was read

 private:
  DatasetInfo info_;
  bool concurrent_ = false;
  int read_ms_ = 0;
};

TEST(ReadAhead, GivesTheFramesInOrderAsReadingThemInTurn) {
  for (const int ahead : {0, 1, 3}) {
    CountingReader reader(20, true);
    {
      ReadAhead frames(reader, 5, 17, ahead, ahead);
      for (std::size_t i = 5; i < 17; ++i) {
        EXPECT_EQ(frames.left(), 17 - i);
        const RgbdFrame f = frames.next();
        ++reader.taken;
        EXPECT_EQ(f.index, i) << "ahead " << ahead;
        EXPECT_EQ(f.depth_m(3, 2), static_cast<float>(i));
      }
      EXPECT_EQ(frames.left(), 0u);
      EXPECT_TRUE(test::contains(test::message_of([&] { frames.next(); }), "past the end"));
    }
    EXPECT_EQ(reader.reads, 12) << "each frame read once, none beyond the end";
    // A frame is read at most `ahead` frames before it is taken (one more while the taken one
    // is counted), on a thread of its own when reading ahead.
    EXPECT_LE(reader.most_ahead, ahead + 1) << "ahead " << ahead;
    if (ahead == 0)
      EXPECT_EQ(reader.reads_elsewhere, 0);
    else
      EXPECT_EQ(reader.reads_elsewhere, 12);
  }
}

TEST(ReadAhead, FramesAndThreadsOutsideTheirRangeAreRefused) {
  CountingReader reader(4);
  for (const std::pair<int, int>& bad : {std::pair{-1, 1}, {65, 1}, {2, -1}, {2, 65}})
    EXPECT_TRUE(
        test::contains(test::message_of([&] { ReadAhead(reader, 0, 4, bad.first, bad.second); }),
                       "must be in [0, 64]"))
        << bad.first << " " << bad.second;
  EXPECT_EQ(reader.reads, 0);
}

TEST(ReadAhead, SeveralThreadsReadAtOnceOnlyWhereTheDatasetAllowsIt) {
  for (const bool concurrent : {false, true}) {
    CountingReader reader(24, concurrent, 5);
    ReadAhead frames(reader, 0, 24, 6, 3);
    for (std::size_t i = 0; i < 24; ++i) {
      EXPECT_EQ(frames.next().index, i);
      ++reader.taken;
    }
    EXPECT_LE(reader.most_ahead, 7);
    if (concurrent) {
      EXPECT_GT(reader.most_at_once, 1) << "three threads, 5 ms a read";
      EXPECT_LE(reader.most_at_once, 3);
    } else {
      EXPECT_EQ(reader.most_at_once, 1) << "the dataset reads one frame at a time";
    }
  }
}

/// The reading threads and the constructing thread's parallel loops share the cores instead of
/// asking for them twice (OpenMP's spinning teams then wait on descheduled threads).
TEST(ReadAhead, TheReadersAndTheCallerShareTheCores) {
  const int before = thread_count();
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  for (const bool concurrent : {true, false}) {
    SCOPED_TRACE(concurrent ? "several readers" : "one reader");
    CountingReader reader(8, concurrent);
    {
      ReadAhead frames(reader, 0, 8, 4, 2);
      // Several readers: one thread each; one: both threads for its loops (no more than ours).
      // The caller keeps at least one thread, never gains any, and together with the readers
      // asks for no more than the cores, giving up only what they take.
      const int readers_use = concurrent ? 2 : std::min(2, before);
      const int now = thread_count();
      SCOPED_TRACE(testing::Message()
                   << cores << " cores, " << before << " threads before, " << now << " during");
      EXPECT_GE(now, 1);
      EXPECT_LE(now, before);
      if (now > 1) {
        EXPECT_LE(now + readers_use, cores);
      }
      if (now < before) {
        EXPECT_GE(now + readers_use, cores);
      }
      for (std::size_t i = 0; i < 8; ++i) EXPECT_EQ(frames.next().index, i);
      EXPECT_EQ(reader.reads_elsewhere, 8);
      EXPECT_EQ(reader.loop_threads, concurrent ? 1 : std::min(2, before));
    }
    EXPECT_EQ(thread_count(), before) << "restored once reading stops";
  }
  // Reading in turn takes nothing from the caller.
  CountingReader reader(2, true);
  ReadAhead in_turn(reader, 0, 2, 0, 4);
  EXPECT_EQ(thread_count(), before);
}

TEST(ReadAhead, AFrameThatCannotBeReadThrowsAtItsTurnAndTheRestFollow) {
  CountingReader reader(8, true);
  reader.bad = 2;
  reader.odd = 5;
  ReadAhead frames(reader, 0, 8, 3, 2);
  for (std::size_t i = 0; i < 8; ++i) {
    if (i == reader.bad) {
      const Error e = test::error_of([&] { frames.next(); });
      EXPECT_EQ(e.code(), ErrorCode::Io);
      EXPECT_TRUE(test::contains(e.what(), "counting/frame2.png: truncated")) << e.what();
    } else if (i == reader.odd) {
      EXPECT_THROW(frames.next(), std::runtime_error);
    } else {
      EXPECT_EQ(frames.next().index, i);
    }
  }
}

TEST(ReadAhead, EndsWithoutReadingTheRest) {
  CountingReader reader(1000);
  {
    ReadAhead frames(reader, 0, 1000, 4);
    EXPECT_EQ(frames.next().index, 0u);
    ++reader.taken;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));  // let it fill its 4
  }
  const int read = reader.reads;
  EXPECT_LE(read, 6) << "reading stops at the frames asked for ahead";
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(reader.reads, read) << "nothing is read once it has ended";
}

TEST(ReadAhead, ARunReadingAheadIsARunReadingEachFrameInTurn) {
  SyntheticDataset data = test::small_desk(300);
  RunParams p = test::small_run();
  p.max_frames = 10;
  p.read_ahead_frames = 0;
  const RunResult in_turn = run_reconstruction(data, p);
  p.read_ahead_frames = 3;
  p.read_threads = 2;
  const RunResult ahead = run_reconstruction(data, p);
  const auto& a = in_turn.reconstruction->trajectory();
  const auto& b = ahead.reconstruction->trajectory();
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i)
    EXPECT_TRUE(a[i].T_wc.isApprox(b[i].T_wc, 0.0)) << "pose " << i;
  EXPECT_EQ(in_turn.reconstruction->map().blocks_per_level(),
            ahead.reconstruction->map().blocks_per_level());

  p.read_ahead_frames = 65;
  EXPECT_TRUE(test::contains(test::message_of([&] { p.validate(); }), "read_ahead_frames"));
  p.read_ahead_frames = 0;
  p.read_threads = -1;
  EXPECT_TRUE(test::contains(test::message_of([&] { p.validate(); }), "read_threads"));
}

TEST(ReadAhead, ThePlanReadsOnTheCoresTheLoopLeavesFree) {
  CountingReader one_at_a_time(10), concurrent(10, true);
  RunParams p;
  p.read_threads = 4;
  EXPECT_EQ(read_plan(p, concurrent).threads, 4);
  EXPECT_EQ(read_plan(p, concurrent).frames, 8) << "two frames a thread";
  EXPECT_EQ(read_plan(p, one_at_a_time).threads, 1);
  EXPECT_EQ(read_plan(p, one_at_a_time).frames, 2);
  // What the run's loops keep while the plan reads: as reading by it gives them.
  for (const CountingReader* reader : {&concurrent, &one_at_a_time}) {
    const ReadPlan plan = read_plan(p, *reader);
    CountingReader same(10, reader == &concurrent);
    ReadAhead frames(same, 0, 10, plan.frames, plan.threads);
    EXPECT_EQ(plan.loop_threads, thread_count());
  }
  p.read_ahead_frames = 5;
  EXPECT_EQ(read_plan(p, concurrent).frames, 5);
  p.read_ahead_frames = 0;
  EXPECT_EQ(read_plan(p, concurrent).frames, 0) << "each frame in turn";
  EXPECT_EQ(read_plan(p, concurrent).loop_threads, thread_count()) << "nothing given up";
  // Automatic: a CPU loop on every core leaves none (the default), on fewer the rest.
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  p = RunParams{};
  const int threads = thread_count();
  set_thread_count(cores);
  EXPECT_EQ(read_plan(p, concurrent).frames, 0);
  if (cores > 1) {
    set_thread_count(1);
    EXPECT_EQ(read_plan(p, concurrent).threads, std::min(cores - 1, 8));
    EXPECT_EQ(read_plan(p, one_at_a_time).threads, 1);
  }
  set_thread_count(threads);
}

}  // namespace
}  // namespace hivox

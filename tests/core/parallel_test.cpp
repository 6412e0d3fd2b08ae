// The launch points every driver loop goes through, and the device they dispatch on.

#include "core/parallel.h"

#include <gtest/gtest.h>

#include <atomic>
#include <vector>

#include "hivox/core/error.h"
#include "test_util.h"

namespace hivox {
namespace {

TEST(ParallelFor, EveryIndexOnceWhateverTheSchedule) {
  for (const int threads : {1, 3}) {
    set_thread_count(threads);
    for (const int64_t n : {0, 1, 7, 1000}) {
      for (const CpuSchedule schedule : {CpuSchedule{}, CpuSchedule::dynamic(16)}) {
        std::vector<int> hits(static_cast<std::size_t>(n), 0);
        int* h = hits.data();
        parallel_for(
            Device::cpu(), n, [=](int64_t i) { ++h[i]; }, schedule);
        for (int64_t i = 0; i < n; ++i) ASSERT_EQ(hits[i], 1) << i << " of " << n;
      }
    }
  }
  set_thread_count(0);
}

TEST(ThreadTeam, SharesLoopsAndRunsSinglesOnce) {
  set_thread_count(3);
  constexpr int64_t n = 1001;
  std::vector<std::atomic<int>> hits(n);
  std::vector<std::atomic<int>> shared(n);
  std::atomic<int> singles{0}, members{0};
  int team_size = 0;
  parallel_team([&](const ThreadTeam& team) {
    ++members;
    team.for_each(
        n, [&](int64_t i) { ++hits[i]; }, CpuSchedule::dynamic(7));
    team.single([&] {
      ++singles;
      team_size = team.size();
    });
    const ThreadTeam::Share s = team.static_share(n);
    for (int64_t i = s.begin; i < s.end; ++i) ++shared[i];
    team.barrier();
  });
  set_thread_count(0);
  EXPECT_EQ(singles, 1);
  EXPECT_EQ(members, team_size);
  for (int64_t i = 0; i < n; ++i) {
    ASSERT_EQ(hits[i], 1) << i;
    ASSERT_EQ(shared[i], 1) << i;  // the static shares partition the items
  }
}

TEST(Device, ParsesPrintsAndNamesWhatThisBuildCannotRun) {
  EXPECT_EQ(Device::parse("cpu"), Device::cpu());
  EXPECT_EQ(Device::parse("cuda"), Device::cuda(0));
  EXPECT_EQ(Device::parse("cuda:2"), Device::cuda(2));
  EXPECT_EQ(Device::cuda(1).to_string(), "cuda:1");
  for (const char* bad : {"gpu", "cuda:", "cuda:-1", "cuda:1x", ""})
    EXPECT_THROW(Device::parse(bad), Error) << bad;
  EXPECT_NO_THROW(Device::cpu().require_available());
  try {
    Device::cuda(0).require_available();
    FAIL() << "no CUDA backend in this build";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::Unsupported);
    EXPECT_TRUE(test::contains(e.what(), "cuda:0")) << e.what();
  }
  try {
    dispatch(Device::cuda(0), "meshing", [] { return 1; });
    FAIL() << "no CUDA implementation";
  } catch (const Error& e) {
    EXPECT_TRUE(test::contains(e.what(), "meshing")) << e.what();
  }
  EXPECT_EQ(dispatch(Device::cpu(), "meshing", [] { return 7; }), 7);
}

}  // namespace
}  // namespace hivox

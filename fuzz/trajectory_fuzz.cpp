// Fuzz target: TUM trajectories (groundtruth.txt, --poses files, eval ate). A file that reads
// must also survive being written and read back with the same number of poses.

#include "fuzz_support.h"
#include "hivox/io/trajectory_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace hivox;
  const std::filesystem::path path = fuzz::input_file("trajectory.txt", data, size);
  fuzz::expect_result_or_clear_error(path.string(), [&] {
    std::vector<StampedPose> poses = read_tum_trajectory(path);
    (void)timestamp_order_problems(poses);
    if (!poses.empty()) (void)find_nearest_pose(poses, poses.front().timestamp_s);
    const std::filesystem::path copy = fuzz::scratch_dir() / "trajectory-copy.txt";
    write_tum_trajectory(copy, poses);
    if (read_tum_trajectory(copy).size() != poses.size())
      fuzz::finding("a trajectory written and read back changed its pose count");
  });
  return 0;
}

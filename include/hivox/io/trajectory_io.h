#pragma once
/// @file
/// TUM trajectory files: one `t tx ty tz qx qy qz qw` line per pose (camera-to-world), `#`
/// comments and blank lines allowed.

#include <filesystem>
#include <string>
#include <vector>

#include "hivox/core/pose.h"

namespace hivox {

/// Reads a TUM trajectory. A malformed line is an `Error(InvalidData)` naming the file and the
/// line number; a missing file is `Error(Io)`. Poses come back in file order.
std::vector<StampedPose> read_tum_trajectory(const std::filesystem::path& path);

/// Writes a TUM trajectory (timestamps with 6 decimals, poses with 9).
void write_tum_trajectory(const std::filesystem::path& path, const std::vector<StampedPose>& poses,
                          const std::string& header_comment = "");

/// What is wrong with the order of `poses`' timestamps, in words ("2 timestamps duplicated, 1
/// out of order"), or empty when each is later than the one before.
std::string timestamp_order_problems(const std::vector<StampedPose>& poses);

/// Index of the pose whose timestamp is nearest to `t_s` if within `max_dt_s` (TUM's rule uses
/// 0.02 s), else -1. `poses` must be sorted by time.
long find_nearest_pose(const std::vector<StampedPose>& poses, double t_s, double max_dt_s = 0.02);

}  // namespace hivox

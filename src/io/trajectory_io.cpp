#include "hivox/io/trajectory_io.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include <fmt/format.h>

#include "hivox/core/error.h"
#include "hivox/io/atomic_file.h"
#include "hivox/io/text_lines.h"

namespace hivox {

std::vector<StampedPose> read_tum_trajectory(const std::filesystem::path& path) {
  std::vector<StampedPose> poses;
  static const char* kNames[] = {"timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"};
  for (const TextLine& line : read_text_lines(path)) {
    if (line.fields.size() != 8)
      fail(ErrorCode::InvalidData, "{}:{}: expected 8 values 't tx ty tz qx qy qz qw', found {}",
           path.string(), line.number, line.fields.size());
    double v[8];
    for (std::size_t i = 0; i < 8; ++i) v[i] = parse_double(path, line, i, kNames[i]);
    StampedPose p;
    p.timestamp_s = v[0];
    try {
      p.T_wc = pose_from_tum(v[1], v[2], v[3], v[4], v[5], v[6], v[7]);
    } catch (const Error& e) {
      fail(ErrorCode::InvalidData, "{}:{}: {}", path.string(), line.number, e.what());
    }
    poses.push_back(p);
  }
  return poses;
}

void write_tum_trajectory(const std::filesystem::path& path, const std::vector<StampedPose>& poses,
                          const std::string& header_comment) {
  AtomicFile file(path);
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(file.temp_path().c_str(), "w"),
                                                    &std::fclose);
  if (!f) fail(ErrorCode::Io, "{}: cannot open for writing", path.string());
  if (!header_comment.empty()) std::fprintf(f.get(), "# %s\n", header_comment.c_str());
  std::fprintf(f.get(), "# timestamp tx ty tz qx qy qz qw (camera-to-world)\n");
  for (const StampedPose& p : poses) {
    const auto v = to_tum(p.T_wc);
    std::fprintf(f.get(), "%.6f %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n", p.timestamp_s, v[0], v[1],
                 v[2], v[3], v[4], v[5], v[6]);
  }
  if (std::fclose(f.release()) != 0) fail(ErrorCode::Io, "{}: write failed", path.string());
  file.commit();
}

std::string timestamp_order_problems(const std::vector<StampedPose>& poses) {
  std::size_t duplicated = 0, backwards = 0;
  std::vector<double> sorted;
  sorted.reserve(poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    sorted.push_back(poses[i].timestamp_s);
    if (i > 0) backwards += poses[i].timestamp_s < poses[i - 1].timestamp_s;
  }
  std::sort(sorted.begin(), sorted.end());
  for (std::size_t i = 1; i < sorted.size(); ++i) duplicated += sorted[i] == sorted[i - 1];
  std::string out;
  if (duplicated > 0) out = fmt::format("{} timestamp(s) duplicated", duplicated);
  if (backwards > 0)
    out += fmt::format("{}{} timestamp(s) out of order", out.empty() ? "" : ", ", backwards);
  return out;
}

long find_nearest_pose(const std::vector<StampedPose>& poses, double t_s, double max_dt_s) {
  if (poses.empty()) return -1;
  const auto it =
      std::lower_bound(poses.begin(), poses.end(), t_s,
                       [](const StampedPose& p, double t) { return p.timestamp_s < t; });
  long best = -1;
  double best_dt = max_dt_s;
  for (auto c : {it, it == poses.begin() ? it : std::prev(it)}) {
    if (c == poses.end()) continue;
    const double dt = std::abs(c->timestamp_s - t_s);
    if (dt <= best_dt) {
      best_dt = dt;
      best = static_cast<long>(c - poses.begin());
    }
  }
  return best;
}

}  // namespace hivox

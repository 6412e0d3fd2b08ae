// TUM RGB-D layout: associations.txt or rgb.txt + depth.txt, groundtruth.txt, intrinsics.json.

#include <algorithm>
#include <cctype>

#include <fmt/format.h>

#include "hivox/core/error.h"
#include "hivox/io/text_lines.h"
#include "hivox/io/trajectory_io.h"
#include "io/dataset_internal.h"

namespace hivox::detail {

namespace fs = std::filesystem;

namespace {

constexpr double kMaxAssociationDtS = 0.02;  // TUM's rule for rgb/depth and ground truth

struct Stamped {
  double timestamp_s = 0;
  std::string file;
};

/// `timestamp filename` lists (rgb.txt, depth.txt).
std::vector<Stamped> read_stamped_list(const fs::path& path) {
  std::vector<Stamped> out;
  for (const TextLine& line : read_text_lines(path)) {
    if (line.fields.size() < 2)
      fail(ErrorCode::InvalidData, "{}:{}: expected 'timestamp filename', found {} field(s)",
           path.string(), line.number, line.fields.size());
    out.push_back({parse_double(path, line, 0, "timestamp"), line.fields[1]});
  }
  if (out.empty())
    fail(ErrorCode::InvalidData, "{}: lists no images (the file is empty or all comments)",
         path.string());
  return out;
}

/// True when a folder on the way to `file` is called depth* (depth/, depth_registered/, ...).
bool lies_under_depth_folder(const std::string& file) {
  for (const fs::path& part : fs::path(file).parent_path()) {
    std::string name = part.string();
    for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (name.starts_with("depth")) return true;
  }
  return false;
}

/// Which column pair of associations.txt holds depth: 2 (`t_rgb rgb t_depth depth`, TUM's
/// order) or 0 (the reverse). Decided on the first line, by folder name, else by file content.
std::size_t depth_column(const fs::path& dir, const fs::path& path, const TextLine& first) {
  const std::string& a = first.fields[1];
  const std::string& b = first.fields[3];
  const bool a_dir = lies_under_depth_folder(a), b_dir = lies_under_depth_folder(b);
  if (b_dir != a_dir) return b_dir ? 2 : 0;
  const bool a_png = is_depth16_png(dir / a), b_png = is_depth16_png(dir / b);
  if (b_png != a_png) return b_png ? 2 : 0;
  std::error_code ec;
  if (!fs::exists(dir / a, ec) && !fs::exists(dir / b, ec))
    fail(ErrorCode::Io, "{}:{}: listed images '{}' and '{}' do not exist in {}", path.string(),
         first.number, a, b, dir.string());
  fail(ErrorCode::InvalidData,
       "{}:{}: cannot tell which column is depth: '{}' and '{}' both {} under a depth/ folder "
       "and both {} 16-bit PNGs",
       path.string(), first.number, a, b, a_dir ? "lie" : "do not lie", a_png ? "are" : "are not");
}

std::vector<FrameFiles> read_associations(const fs::path& dir, const fs::path& path) {
  const std::vector<TextLine> lines = read_text_lines(path);
  if (lines.empty())
    fail(ErrorCode::InvalidData,
         "{}: the association list is empty (no 't_rgb rgb_file t_depth depth_file' lines)",
         path.string());
  for (const TextLine& line : lines)
    if (line.fields.size() < 4)
      fail(ErrorCode::InvalidData,
           "{}:{}: expected 't_rgb rgb_file t_depth depth_file', found {} field(s)", path.string(),
           line.number, line.fields.size());
  const std::size_t d = depth_column(dir, path, lines.front());
  const std::size_t c = 2 - d;
  std::vector<FrameFiles> frames;
  frames.reserve(lines.size());
  for (const TextLine& line : lines) {
    FrameFiles f;
    parse_double(path, line, c, "colour timestamp");  // checked, not used: frames go by depth
    f.timestamp_s = parse_double(path, line, d, "depth timestamp");
    f.depth = dir / line.fields[d + 1];
    f.color = dir / line.fields[c + 1];
    frames.push_back(std::move(f));
  }
  return frames;
}

std::vector<FrameFiles> read_rgb_depth_lists(const fs::path& dir) {
  const fs::path depth_txt = dir / "depth.txt", rgb_txt = dir / "rgb.txt";
  const std::vector<Stamped> depth = read_stamped_list(depth_txt);
  std::vector<FrameFiles> frames;
  std::error_code ec;
  if (!fs::is_regular_file(rgb_txt, ec)) {  // depth only
    for (const Stamped& s : depth) frames.push_back({dir / s.file, {}, s.timestamp_s, {}, {}});
    std::stable_sort(frames.begin(), frames.end(), [](const FrameFiles& a, const FrameFiles& b) {
      return a.timestamp_s < b.timestamp_s;
    });
    return frames;
  }
  const std::vector<Stamped> rgb = read_stamped_list(rgb_txt);
  std::vector<double> t_rgb, t_depth;
  for (const Stamped& s : rgb) t_rgb.push_back(s.timestamp_s);
  for (const Stamped& s : depth) t_depth.push_back(s.timestamp_s);
  for (const auto& [r, d] : associate_timestamps(t_rgb, t_depth, kMaxAssociationDtS))
    frames.push_back({dir / depth[d].file, dir / rgb[r].file, depth[d].timestamp_s, {}, {}});
  if (frames.empty())
    fail(ErrorCode::InvalidData,
         "{} and {}: no colour/depth pair within {} s of each other (empty association)",
         rgb_txt.string(), depth_txt.string(), kMaxAssociationDtS);
  return frames;
}

}  // namespace

std::unique_ptr<FileDataset> open_tum(const fs::path& dir, const DatasetParams& params) {
  std::error_code ec;
  const fs::path associations = dir / "associations.txt";
  std::vector<FrameFiles> frames = fs::is_regular_file(associations, ec)
                                       ? read_associations(dir, associations)
                                       : read_rgb_depth_lists(dir);

  DatasetInfo info;
  const fs::path groundtruth = dir / "groundtruth.txt";
  if (fs::is_regular_file(groundtruth, ec)) {
    std::vector<StampedPose> gt = read_tum_trajectory(groundtruth);
    std::stable_sort(gt.begin(), gt.end(), [](const StampedPose& a, const StampedPose& b) {
      return a.timestamp_s < b.timestamp_s;
    });
    std::size_t matched = 0;
    for (FrameFiles& f : frames) {
      const long i = find_nearest_pose(gt, f.timestamp_s, kMaxAssociationDtS);
      if (i < 0) continue;
      f.T_wc_gt = gt[static_cast<std::size_t>(i)].T_wc;
      ++matched;
    }
    if (matched == 0)
      info.warnings.push_back(fmt::format(
          "{} has {} poses, but none lies within {} s of a depth frame: no ground truth",
          groundtruth.string(), gt.size(), kMaxAssociationDtS));
  }

  const Calibration calibration =
      resolve_calibration(dir, params,
                          {.layout_name = "TUM",
                           .preset = nullptr,
                           .guess_from_folder_name = true,
                           .depth_scale = 5000,
                           .depth_scale_source = "TUM default (intrinsics.json has none)"});
  info.source = dir.string();
  info.layout = DatasetLayout::Tum;
  info.timestamps_recorded = true;
  calibration.apply_to(info, params.undistort);  // TUM depth is registered to colour
  return std::make_unique<FileDataset>(std::move(info), std::move(frames),
                                       DepthDecoding{calibration.depth_scale, 0, 0.0});
}

}  // namespace hivox::detail

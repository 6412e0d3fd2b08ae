// Folders of numbered images: Open3D's reconstruction-system / RealSense-recorder layout
// (`depth/`, `color/`, `camera_intrinsic.json`), bare folders of depth PNGs (a `depth/` folder,
// or the PNGs themselves; colour in `color/` or `rgb/` when present), whose camera comes from a
// preset or an intrinsics file, the Replica renders of NICE-SLAM-style tools (`results/`,
// `traj.txt`, `cam_params.json`) and ScanNet's exported frames (`color/`, `depth/`, `pose/`,
// `intrinsic/`).

#include <algorithm>
#include <fstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "hivox/core/error.h"
#include "hivox/io/atomic_file.h"
#include "hivox/io/image_io.h"
#include "hivox/io/text_lines.h"
#include "io/dataset_internal.h"

namespace hivox::detail {

namespace fs = std::filesystem;

namespace {

/// The image files of `dir` with one of `extensions`, sorted by name (numbered names sort in
/// frame order when zero-padded, as recorders write them).
std::vector<fs::path> images_in(const fs::path& dir,
                                std::initializer_list<const char*> extensions) {
  std::vector<fs::path> out;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    if (!it->is_regular_file(ec)) continue;
    std::string ext = it->path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    for (const char* e : extensions)
      if (ext == e) out.push_back(it->path());
  }
  if (ec) fail(ErrorCode::Io, "{}: cannot list the folder ({})", dir.string(), ec.message());
  std::sort(out.begin(), out.end());
  return out;
}

/// Where the depth images of a folder layout are: `dir/depth`, or `dir` itself when it holds
/// 16-bit PNGs. Empty when neither.
fs::path depth_folder(const fs::path& dir) {
  std::error_code ec;
  if (fs::is_directory(dir / "depth", ec)) return dir / "depth";
  for (const fs::path& p : images_in(dir, {".png"}))
    if (is_depth16_png(p)) return dir;
  return {};
}

/// Open3D's `camera_intrinsic.json`: width, height and a column-major 3x3 `intrinsic_matrix`.
CameraPreset read_open3d_intrinsics(const fs::path& path) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(read_whole_file(path));
  } catch (const nlohmann::json::exception& e) {
    fail(ErrorCode::InvalidData, "{}: not valid JSON ({})", path.string(), e.what());
  }
  auto bad = [&](const std::string& why) {
    fail(ErrorCode::InvalidData,
         "{}: {} (Open3D's format: width, height, intrinsic_matrix of 9 "
         "numbers, column-major)",
         path.string(), why);
  };
  if (!j.is_object() || !j.contains("width") || !j.contains("height") ||
      !j.contains("intrinsic_matrix"))
    bad("needs width, height and intrinsic_matrix");
  const nlohmann::json& k = j["intrinsic_matrix"];
  if (!j["width"].is_number_integer() || !j["height"].is_number_integer() || !k.is_array() ||
      k.size() != 9 ||
      !std::all_of(k.begin(), k.end(), [](const auto& v) { return v.is_number(); }))
    bad("width and height must be integers and intrinsic_matrix 9 numbers");
  CameraPreset p;
  p.name = "camera_intrinsic.json";
  p.camera = {k[0].get<float>(), k[4].get<float>(),     k[6].get<float>(),
              k[7].get<float>(), j["width"].get<int>(), j["height"].get<int>()};
  try {
    p.camera.validate(path.string());
  } catch (const Error& e) {
    bad(e.what());
  }
  p.depth_scale = 1000.0;  // Open3D's default depth_scale (millimetres)
  p.description = "Open3D camera_intrinsic.json";
  return p;
}

/// The calibration of a layout whose camera file `file` (read by `read`; none when empty)
/// applies unless the user gives a preset or an intrinsics file; `depth_scale` is the layout's
/// own when nothing else gives one (0: none).
template <typename Read>
Calibration calibrate(const fs::path& dir, const DatasetParams& params, const char* layout,
                      const fs::path& file, Read read, double depth_scale = 0,
                      const char* depth_scale_source = "") {
  std::optional<CameraPreset> camera;
  const std::string name = file.string();  // outlives the preset's name view
  if (!file.empty() && params.preset.empty() && params.intrinsics_path.empty()) {
    camera = read(file);
    camera->name = name;
  }
  return resolve_calibration(dir, params,
                             {.layout_name = layout,
                              .preset = camera ? &*camera : nullptr,
                              .guess_from_folder_name = false,
                              .depth_scale = depth_scale,
                              .depth_scale_source = depth_scale_source,
                              .preset_is_file = true});
}

}  // namespace

bool is_image_folder_layout(const fs::path& dir) {
  return !depth_folder(dir).empty();
}

std::unique_ptr<FileDataset> open_image_folders(const fs::path& dir, const DatasetParams& params) {
  const fs::path depth_dir = depth_folder(dir);
  if (depth_dir.empty())
    fail(ErrorCode::InvalidData, "{}: no depth/ folder and no 16-bit depth PNGs", dir.string());
  const std::vector<fs::path> depths = images_in(depth_dir, {".png"});
  if (depths.empty())
    fail(ErrorCode::InvalidData, "{}: no depth PNGs in the folder", depth_dir.string());
  std::error_code ec;
  fs::path color_dir;
  for (const char* name : {"color", "rgb", "image"})
    if (fs::is_directory(dir / name, ec)) {
      color_dir = dir / name;
      break;
    }
  std::vector<fs::path> colors;
  if (!color_dir.empty()) {
    colors = images_in(color_dir, {".jpg", ".jpeg", ".png"});
    if (colors.size() != depths.size())
      fail(ErrorCode::InvalidData,
           "{}: {} colour images for {} depth images in {}: frames are paired by name order, so "
           "the counts must match",
           color_dir.string(), colors.size(), depths.size(), depth_dir.string());
  }
  std::vector<FrameFiles> frames;
  for (std::size_t i = 0; i < depths.size(); ++i) {
    FrameFiles f;
    f.depth = depths[i];
    if (!colors.empty()) f.color = colors[i];
    f.timestamp_s = static_cast<double>(i) / kFrameRateHz;
    frames.push_back(std::move(f));
  }

  const fs::path open3d_json = dir / "camera_intrinsic.json";
  const bool open3d = fs::is_regular_file(open3d_json, ec);
  const Calibration calibration =
      calibrate(dir, params, open3d ? "Open3D" : "image folder", open3d ? open3d_json : fs::path(),
                read_open3d_intrinsics);
  DatasetInfo info;
  info.source = dir.string();
  info.layout = open3d ? DatasetLayout::Open3d : DatasetLayout::ImageFolder;
  calibration.apply_to(info, params.undistort);
  info.layout_reason =
      open3d
          ? fmt::format(
                "camera_intrinsic.json and {} depth image(s) in {}{}", depths.size(),
                depth_dir.filename().string(),
                colors.empty() ? "" : fmt::format(", colour in {}", color_dir.filename().string()))
          : fmt::format(
                "{} 16-bit depth PNG(s) in {}{}; no layout file", depths.size(),
                depth_dir == dir ? "the folder" : depth_dir.filename().string(),
                colors.empty() ? "" : fmt::format(", colour in {}", color_dir.filename().string()));
  return std::make_unique<FileDataset>(std::move(info), std::move(frames),
                                       DepthDecoding{calibration.depth_scale, 0, 0.0});
}

namespace {

/// The frame number of a file named PREFIX + digits + extension, or -1.
long frame_number(const fs::path& p, std::string_view prefix) {
  const std::string stem = p.stem().string();
  if (!stem.starts_with(prefix) || stem.size() == prefix.size() || stem.size() > prefix.size() + 9)
    return -1;
  const std::string digits = stem.substr(prefix.size());
  if (!std::all_of(digits.begin(), digits.end(),
                   [](char c) { return std::isdigit(static_cast<unsigned char>(c)); }))
    return -1;
  return std::stol(digits);
}

/// `results/` files named PREFIX + number, by number.
std::vector<std::pair<long, fs::path>> numbered(const fs::path& dir, std::string_view prefix,
                                                std::initializer_list<const char*> extensions) {
  std::vector<std::pair<long, fs::path>> out;
  for (const fs::path& p : images_in(dir, extensions))
    if (const long n = frame_number(p, prefix); n >= 0) out.emplace_back(n, p);
  std::sort(out.begin(), out.end());
  return out;
}

/// NICE-SLAM's `cam_params.json` ({"camera": {w, h, fx, fy, cx, cy, scale}}), its principal
/// point moved by -0.5 px: NICE-SLAM's renderer puts pixel centres at +0.5, hivox at integers
/// (on Replica office0, depth back-projected with the file's cx, cy lies a median 1.28 mm from
/// the true mesh, with them moved 0.17 mm).
CameraPreset read_replica_camera(const fs::path& path) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(read_whole_file(path));
  } catch (const nlohmann::json::exception& e) {
    fail(ErrorCode::InvalidData, "{}: not valid JSON ({})", path.string(), e.what());
  }
  const nlohmann::json* c = j.is_object() && j.contains("camera") ? &j["camera"] : nullptr;
  for (const char* k : {"w", "h", "fx", "fy", "cx", "cy", "scale"})
    if (c == nullptr || !c->is_object() || !c->contains(k) || !(*c)[k].is_number())
      fail(ErrorCode::InvalidData,
           "{}: needs \"camera\" with numbers w, h, fx, fy, cx, cy and scale (NICE-SLAM's format)",
           path.string());
  CameraPreset p;
  p.name = "cam_params.json";
  p.camera = {(*c)["fx"].get<float>(),        (*c)["fy"].get<float>(),
              (*c)["cx"].get<float>() - 0.5f, (*c)["cy"].get<float>() - 0.5f,
              (*c)["w"].get<int>(),           (*c)["h"].get<int>()};
  try {
    p.camera.validate(path.string());
  } catch (const Error& e) {
    fail(ErrorCode::InvalidData, "{}", e.what());
  }
  p.depth_scale = (*c)["scale"].get<double>();
  if (!(p.depth_scale > 0))
    fail(ErrorCode::InvalidData, "{}: scale must be > 0 (raw depth units per metre)",
         path.string());
  p.description = "NICE-SLAM cam_params.json";
  return p;
}

fs::path replica_camera_file(const fs::path& dir) {
  std::error_code ec;
  for (const fs::path& p : {dir / "cam_params.json", dir.parent_path() / "cam_params.json"})
    if (fs::is_regular_file(p, ec)) return p;
  return {};
}

}  // namespace

bool is_replica_layout(const fs::path& dir) {
  std::error_code ec;
  return fs::is_directory(dir / "results", ec) && fs::is_regular_file(dir / "traj.txt", ec);
}

std::unique_ptr<FileDataset> open_replica(const fs::path& dir, const DatasetParams& params) {
  const fs::path results = dir / "results";
  const auto depths = numbered(results, "depth", {".png"});
  if (depths.empty())
    fail(ErrorCode::InvalidData, "{}: no depthNNNNNN.png files", results.string());
  const auto colors = numbered(results, "frame", {".jpg", ".jpeg", ".png"});
  // The trajectory: one 4x4 camera-to-world matrix per line, frame n on line n.
  const fs::path traj = dir / "traj.txt";
  std::vector<Pose> poses;
  for (const TextLine& line : read_text_lines(traj)) {
    if (line.fields.size() != 16)
      fail(ErrorCode::InvalidData, "{}:{}: {} numbers, expected 16 (a 4x4 matrix, row-major)",
           traj.string(), line.number, line.fields.size());
    std::vector<double> v;
    for (std::size_t i = 0; i < 16; ++i) v.push_back(parse_double(traj, line, i, "matrix entry"));
    poses.push_back(pose_from_row_major(v, fmt::format("{}:{}", traj.string(), line.number)));
  }
  std::vector<FrameFiles> frames;
  std::size_t ci = 0;
  for (const auto& [n, depth] : depths) {
    FrameFiles f;
    f.depth = depth;
    while (ci < colors.size() && colors[ci].first < n) ++ci;
    if (!colors.empty()) {
      if (ci == colors.size() || colors[ci].first != n)
        fail(ErrorCode::InvalidData, "{}: no frame{:06d} colour image for {}", results.string(), n,
             depth.filename().string());
      f.color = colors[ci].second;
    }
    if (static_cast<std::size_t>(n) >= poses.size())
      fail(ErrorCode::InvalidData, "{}: {} poses, none for {}", traj.string(), poses.size(),
           depth.filename().string());
    f.T_wc_gt = poses[static_cast<std::size_t>(n)];
    f.timestamp_s = static_cast<double>(n) / kFrameRateHz;
    frames.push_back(std::move(f));
  }
  const fs::path camera_file = replica_camera_file(dir);
  const Calibration calibration =
      calibrate(dir, params, "Replica", camera_file, read_replica_camera);
  DatasetInfo info;
  info.source = dir.string();
  info.layout = DatasetLayout::Replica;
  calibration.apply_to(info, params.undistort);
  info.has_ground_truth = true;
  info.rig.depth_noise = SensorNoise::none();  // rendered depth
  info.layout_reason =
      fmt::format("results/ with {} depthNNNNNN.png{}, traj.txt with {} poses{}", depths.size(),
                  colors.empty() ? "" : " and frameNNNNNN colour images", poses.size(),
                  camera_file.empty() ? "" : fmt::format(", camera from {}", camera_file.string()));
  if (info.intrinsics_source == camera_file.string())
    info.intrinsics_source += " (principal point -0.5 px: NICE-SLAM's pixel centres)";
  return std::make_unique<FileDataset>(std::move(info), std::move(frames),
                                       DepthDecoding{calibration.depth_scale, 0, 0.0});
}

namespace {

/// Numbers of a text file (whitespace-separated), checked to be `count` finite values; `nullopt`
/// when `allow_infinite` and any is infinite (ScanNet marks frames without a pose with -inf).
std::optional<std::vector<double>> read_numbers(const fs::path& path, std::size_t count,
                                                bool allow_infinite) {
  std::vector<double> v;
  bool infinite = false;
  for (const TextLine& line : read_text_lines(path))
    for (std::size_t i = 0; i < line.fields.size(); ++i) {
      const std::string& f = line.fields[i];
      if (allow_infinite && (f == "-inf" || f == "inf" || f == "nan")) {
        infinite = true;
        v.push_back(0.0);
        continue;
      }
      v.push_back(parse_double(path, line, i, "number"));
    }
  if (v.size() != count)
    fail(ErrorCode::InvalidData, "{}: {} numbers, expected {}", path.string(), v.size(), count);
  if (infinite) return std::nullopt;
  return v;
}

/// A camera from ScanNet's 4x4 `intrinsic_*.txt` and the size of the images it takes.
PinholeCamera scannet_camera(const fs::path& path, int width, int height) {
  const std::vector<double> k = *read_numbers(path, 16, false);
  PinholeCamera c{static_cast<float>(k[0]),
                  static_cast<float>(k[5]),
                  static_cast<float>(k[2]),
                  static_cast<float>(k[6]),
                  width,
                  height};
  c.validate(path.string());
  return c;
}

}  // namespace

bool is_scannet_layout(const fs::path& dir) {
  std::error_code ec;
  return fs::is_directory(dir / "depth", ec) && fs::is_directory(dir / "pose", ec) &&
         fs::is_regular_file(dir / "intrinsic" / "intrinsic_depth.txt", ec);
}

std::unique_ptr<FileDataset> open_scannet(const fs::path& dir, const DatasetParams& params) {
  const auto depths = numbered(dir / "depth", "", {".png"});
  if (depths.empty())
    fail(ErrorCode::InvalidData, "{}: no numbered depth PNGs (N.png)", (dir / "depth").string());
  std::error_code ec;
  const bool has_color = fs::is_directory(dir / "color", ec);
  const auto colors = has_color ? numbered(dir / "color", "", {".jpg", ".jpeg", ".png"})
                                : std::vector<std::pair<long, fs::path>>{};
  std::vector<FrameFiles> frames;
  std::size_t without_pose = 0;
  std::size_t ci = 0;
  for (const auto& [n, depth] : depths) {
    FrameFiles f;
    f.depth = depth;
    while (ci < colors.size() && colors[ci].first < n) ++ci;
    if (has_color) {
      if (ci == colors.size() || colors[ci].first != n)
        fail(ErrorCode::InvalidData, "{}: no colour image {}.jpg for {}", (dir / "color").string(),
             n, depth.filename().string());
      f.color = colors[ci].second;
    }
    const fs::path pose = dir / "pose" / (std::to_string(n) + ".txt");
    if (fs::is_regular_file(pose, ec)) {
      if (const auto v = read_numbers(pose, 16, true))
        f.T_wc_gt = pose_from_row_major(*v, pose.string());
    }
    without_pose += !f.T_wc_gt;
    f.timestamp_s = static_cast<double>(n) / kFrameRateHz;
    frames.push_back(std::move(f));
  }
  // Image sizes from the first frame; the intrinsics files carry none.
  const Image<uint16_t> first_depth = read_depth16(frames.front().depth);
  const Calibration calibration = calibrate(
      dir, params, "ScanNet", dir / "intrinsic" / "intrinsic_depth.txt",
      [&](const fs::path& k) {
        CameraPreset p;
        p.camera = scannet_camera(k, first_depth.width(), first_depth.height());
        p.depth_scale = 1000.0;  // millimetres
        p.description = "ScanNet intrinsic_depth.txt";
        return p;
      },
      1000.0, "ScanNet default (mm)");
  DatasetInfo info;
  info.source = dir.string();
  info.layout = DatasetLayout::ScanNet;
  calibration.apply_to(info, params.undistort);
  // Colour has its own camera (ScanNet: 1296x968 beside 640x480 depth), same viewpoint.
  const fs::path color_k = dir / "intrinsic" / "intrinsic_color.txt";
  if (has_color && fs::is_regular_file(color_k, ec)) {
    const ColorImage first_color = read_color(frames.front().color);
    info.rig.color_camera = scannet_camera(color_k, first_color.width(), first_color.height());
  }
  info.has_ground_truth = without_pose < frames.size();
  info.layout_reason =
      fmt::format("depth/, pose/ and intrinsic/intrinsic_depth.txt with {} frames{}{}",
                  frames.size(), has_color ? ", colour in color/" : "",
                  without_pose > 0 ? fmt::format(" ({} without a valid pose)", without_pose) : "");
  return std::make_unique<FileDataset>(std::move(info), std::move(frames),
                                       DepthDecoding{calibration.depth_scale, 0, 0.0});
}

}  // namespace hivox::detail

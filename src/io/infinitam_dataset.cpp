// InfiniTAM layout: calib.txt + numbered frames (0000.pgm depth / 0000.ppm colour, or PNG), in
// the folder or in its Frames/ subfolder.
//
// calib.txt, as InfiniTAM's readRGBDCalib reads it (whitespace-separated, blank lines ignored):
//   colour intrinsics: `width height` / `fx fy` / `cx cy`
//   depth intrinsics:  `width height` / `fx fy` / `cx cy`
//   extrinsics: three rows `r r r t` of a 3x4 matrix InfiniTAM calls `trafo_rgb_to_depth`: it
//     maps points from the colour camera frame into the depth camera frame (InfiniTAM computes
//     the colour camera's world-to-camera matrix as `calib_inv * M_depth`). In hivox names that
//     is T_depth_color, so `DatasetInfo::T_color_depth` holds its inverse.
//   depth conversion: `affine a b` (depth_m = a * raw + b). InfiniTAM also knows `kinect a b` or a
//     bare `a b` (Kinect disparity), which hivox does not read; a bare `0 0` means affine
//     0.001 0 there, and here too.

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "hivox/core/error.h"
#include "hivox/io/image_io.h"
#include "hivox/io/intrinsics_io.h"
#include "hivox/io/text_lines.h"
#include "io/dataset_internal.h"

namespace hivox::detail {

namespace fs = std::filesystem;

namespace {

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

struct InfiniTamCalib {
  PinholeCamera color, depth;
  Pose T_depth_color = Pose::Identity();
  double a = 0, b = 0;  // depth_m = a * raw + b
  std::string depth_line;
};

PinholeCamera parse_intrinsics(const fs::path& path, const std::vector<TextLine>& lines,
                               std::size_t first, const char* which) {
  static const char* kNames[3][2] = {{"width", "height"}, {"fx", "fy"}, {"cx", "cy"}};
  double v[3][2];
  for (std::size_t r = 0; r < 3; ++r) {
    const TextLine& line = lines[first + r];
    if (line.fields.size() != 2)
      fail(ErrorCode::InvalidData, "{}:{}: expected '{} {}' of the {} camera, found {} value(s)",
           path.string(), line.number, kNames[r][0], kNames[r][1], which, line.fields.size());
    for (std::size_t c = 0; c < 2; ++c) v[r][c] = parse_double(path, line, c, kNames[r][c]);
  }
  if (v[0][0] != std::floor(v[0][0]) || v[0][1] != std::floor(v[0][1]))
    fail(ErrorCode::InvalidData, "{}:{}: {} image size must be integers, found {} x {}",
         path.string(), lines[first].number, which, v[0][0], v[0][1]);
  for (const double side : v[0])
    if (!(side >= 1.0 && side <= kMaxImageSide))
      fail(ErrorCode::InvalidData, "{}:{}: {} image size must be in [1, {}], found {} x {}",
           path.string(), lines[first].number, which, kMaxImageSide, v[0][0], v[0][1]);
  PinholeCamera camera{static_cast<float>(v[1][0]), static_cast<float>(v[1][1]),
                       static_cast<float>(v[2][0]), static_cast<float>(v[2][1]),
                       static_cast<int>(v[0][0]),   static_cast<int>(v[0][1])};
  camera.validate(fmt::format("{}:{} ({} intrinsics)", path.string(), lines[first].number, which));
  return camera;
}

InfiniTamCalib read_calib(const fs::path& path) {
  const std::vector<TextLine> lines = read_text_lines(path);
  if (lines.size() < 10)
    fail(ErrorCode::InvalidData,
         "{}: has {} non-empty lines; expected colour intrinsics (3 lines), depth intrinsics (3), "
         "a 3x4 colour-to-depth matrix (3) and the depth line 'affine a b'",
         path.string(), lines.size());
  InfiniTamCalib calib;
  calib.color = parse_intrinsics(path, lines, 0, "colour");
  calib.depth = parse_intrinsics(path, lines, 3, "depth");

  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  for (int r = 0; r < 3; ++r) {
    const TextLine& line = lines[6 + static_cast<std::size_t>(r)];
    if (line.fields.size() != 4)
      fail(ErrorCode::InvalidData,
           "{}:{}: expected a row 'r r r t' of the 3x4 colour-to-depth matrix, found {} value(s)",
           path.string(), line.number, line.fields.size());
    for (int c = 0; c < 3; ++c)
      R(r, c) = parse_double(path, line, static_cast<std::size_t>(c), "rotation entry");
    t(r) = parse_double(path, line, 3, "translation");
  }
  const double error = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (error > 1e-2 || R.determinant() < 0)
    fail(ErrorCode::InvalidData,
         "{}:{}: the colour-to-depth matrix is not a rigid transform (|R^T R - I| = {:.2g})",
         path.string(), lines[6].number, error);
  calib.T_depth_color.linear() = Eigen::Quaterniond(R).normalized().toRotationMatrix();
  calib.T_depth_color.translation() = t;

  const TextLine& line = lines[9];
  const std::string word = lower(line.fields[0]);
  calib.depth_line = fmt::format("{}:{}", path.string(), line.number);
  if (word == "affine") {
    if (line.fields.size() != 3)
      fail(ErrorCode::InvalidData, "{}:{}: expected 'affine a b' (depth_m = a * raw + b)",
           path.string(), line.number);
    calib.a = parse_double(path, line, 1, "affine a");
    calib.b = parse_double(path, line, 2, "affine b");
    if (!(calib.a > 0))
      fail(ErrorCode::InvalidData,
           "{}:{}: affine a (metres per raw depth unit) must be > 0, got {}", path.string(),
           line.number, calib.a);
    return calib;
  }
  const bool bare = line.fields.size() == 2;
  if (bare && line.fields[0] == "0" && line.fields[1] == "0") {  // InfiniTAM: affine 1/1000, 0
    calib.a = 0.001;
    return calib;
  }
  if (word == "kinect" || word == "disparity" || bare)
    fail(ErrorCode::Unsupported,
         "{}:{}: Kinect disparity calibration ('{}') is not supported: hivox reads depth images; "
         "convert the frames to depth and write 'affine a b' (depth_m = a * raw + b)",
         path.string(), line.number, fmt::join(line.fields, " "));
  fail(ErrorCode::InvalidData, "{}:{}: expected the depth line 'affine a b', found '{}'",
       path.string(), line.number, fmt::join(line.fields, " "));
}

/// Numbered images sharing a name pattern: `PREFIX<number>.EXT`.
struct FrameGroup {
  std::string prefix, ext;
  std::map<long, fs::path> files;  // by frame number
  std::string pattern() const {
    const std::size_t digits =
        files.empty() ? 0 : files.begin()->second.stem().string().size() - prefix.size();
    return fmt::format("{}{}.{}", prefix, std::string(digits, '#'), ext);
  }
};

std::vector<FrameGroup> scan_numbered_images(const fs::path& folder) {
  std::map<std::pair<std::string, std::string>, FrameGroup> groups;
  std::error_code ec;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    const fs::path& p = it->path();
    std::string ext = lower(p.extension().string());
    if (ext.empty()) continue;
    ext = ext.substr(1);
    if (ext != "pgm" && ext != "ppm" && ext != "png" && ext != "jpg" && ext != "jpeg") continue;
    const std::string stem = p.stem().string();
    std::size_t first_digit = stem.size();
    while (first_digit > 0 && std::isdigit(static_cast<unsigned char>(stem[first_digit - 1])))
      --first_digit;
    const std::size_t digits = stem.size() - first_digit;
    if (digits == 0 || digits > 9) continue;
    FrameGroup& g = groups[{stem.substr(0, first_digit), ext}];
    g.prefix = stem.substr(0, first_digit);
    g.ext = ext;
    g.files[std::stol(stem.substr(first_digit))] = p;
  }
  std::vector<FrameGroup> out;
  out.reserve(groups.size());
  for (auto& [key, g] : groups) out.push_back(std::move(g));
  return out;
}

bool is_depth_group(const FrameGroup& g) {
  if (g.ext == "pgm") return true;
  if (g.ext != "png") return false;
  const std::string prefix = lower(g.prefix);
  if (prefix.find("depth") != std::string::npos) return true;
  for (const char* colour_word : {"rgb", "color", "colour", "img", "image"})
    if (prefix.find(colour_word) != std::string::npos) return false;
  return is_depth16_png(g.files.begin()->second);
}

const FrameGroup* pick_one(const std::vector<const FrameGroup*>& groups, const fs::path& folder,
                           const char* what) {
  if (groups.size() > 1)
    fail(ErrorCode::InvalidData, "{}: ambiguous {} frames: both {} and {} match", folder.string(),
         what, groups[0]->pattern(), groups[1]->pattern());
  return groups.empty() ? nullptr : groups.front();
}

}  // namespace

std::unique_ptr<FileDataset> open_infinitam(const fs::path& dir, const DatasetParams& params) {
  const fs::path calib_path = dir / "calib.txt";
  const InfiniTamCalib calib = read_calib(calib_path);

  fs::path folder = dir;
  std::vector<FrameGroup> groups = scan_numbered_images(dir);
  std::error_code ec;
  if (groups.empty() && fs::is_directory(dir / "Frames", ec)) {
    folder = dir / "Frames";
    groups = scan_numbered_images(folder);
  }
  std::vector<const FrameGroup*> depth_groups, color_groups;
  for (const FrameGroup& g : groups)
    (is_depth_group(g) ? depth_groups : color_groups).push_back(&g);
  const FrameGroup* depth = pick_one(depth_groups, folder, "depth");
  const FrameGroup* color = pick_one(color_groups, folder, "colour");
  if (!depth)
    fail(ErrorCode::InvalidData,
         "{}: calib.txt found, but no numbered depth frames (e.g. 0000.pgm or depth 16-bit "
         "0000.png) in {} or its Frames/ subfolder",
         dir.string(), dir.string());

  std::vector<FrameFiles> frames;
  frames.reserve(depth->files.size());
  for (const auto& [number, path] : depth->files) {
    FrameFiles f;
    f.depth = path;
    if (color) {
      const auto it = color->files.find(number);
      if (it == color->files.end())
        fail(ErrorCode::InvalidData, "{}: depth frame {} has no colour image (expected {})",
             folder.string(), path.filename().string(), color->pattern());
      f.color = it->second;
    }
    f.timestamp_s = static_cast<double>(frames.size()) / kFrameRateHz;
    frames.push_back(std::move(f));
  }

  DatasetInfo info;
  info.source = dir.string();
  info.layout = DatasetLayout::InfiniTam;
  info.rig.depth_camera = calib.depth;
  info.rig.color_camera = calib.color;
  info.rig.T_color_depth = calib.T_depth_color.inverse();
  info.intrinsics_source = calib_path.string();
  DepthDecoding decoding{1.0 / calib.a, 0, calib.b};
  info.depth_scale_source =
      fmt::format("{} (affine {:g} {:g})", calib.depth_line, calib.a, calib.b);

  // Explicit choices beat the folder: they replace both cameras' intrinsics (the extrinsics and
  // the affine offset stay), and the depth scale unless --depth-scale gives one.
  if (!params.intrinsics_path.empty()) {
    const IntrinsicsFile file = read_intrinsics_json(params.intrinsics_path);
    info.rig.depth_camera = info.rig.color_camera = file.camera;
    info.intrinsics_source = fmt::format("{} (given)", params.intrinsics_path.string());
    if (file.depth_scale > 0) {
      decoding.scale = file.depth_scale;
      info.depth_scale_source = info.intrinsics_source;
    }
  } else if (!params.preset.empty()) {
    const CameraPreset& preset = camera_preset(params.preset);
    info.rig.depth_camera = info.rig.color_camera = preset.camera;
    info.intrinsics_source = fmt::format("preset {} (given)", preset.name);
    decoding.scale = preset.depth_scale;
    info.depth_scale_source = info.intrinsics_source;
  }
  if (params.depth_scale > 0) {
    decoding.scale = params.depth_scale;
    info.depth_scale_source = "given";
  }
  info.rig.depth_scale = decoding.scale;
  return std::make_unique<FileDataset>(std::move(info), std::move(frames), decoding);
}

}  // namespace hivox::detail

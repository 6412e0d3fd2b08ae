// The reader shared by every file layout, and helpers the layouts share: intrinsics / depth
// scale resolution, 4x4 pose files, PNG header sniffing.

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <fstream>

#include <fmt/format.h>

#include "hivox/core/error.h"
#include "hivox/io/image_io.h"
#include "hivox/io/intrinsics_io.h"
#include "hivox/io/text_lines.h"
#include "io/dataset_internal.h"

namespace hivox::detail {

namespace fs = std::filesystem;

namespace {

void check_size(const fs::path& file, const char* what, int width, int height,
                const PinholeCamera& camera, const std::string& intrinsics_source) {
  if (width != camera.width || height != camera.height)
    fail(ErrorCode::InvalidData, "{}: {} image is {}x{}, but the intrinsics ({}) are for {}x{}",
         file.string(), what, width, height, intrinsics_source, camera.width, camera.height);
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

/// `tum_fr1` for a folder called `rgbd_dataset_freiburg1_desk` or `fr1_desk`, etc.
const CameraPreset* guess_preset(const fs::path& dir, std::string* matched_name) {
  std::error_code ec;
  fs::path p = fs::absolute(dir, ec).lexically_normal();
  if (p.filename().empty()) p = p.parent_path();
  // The folder, then its parent (e.g. freiburg1/desk).
  for (const fs::path& candidate : {p, p.parent_path()}) {
    const std::string name = lower(candidate.filename().string());
    if (name.empty()) continue;
    std::vector<std::string> tokens;
    std::string token;
    for (char c : name + " ") {
      if (std::isalnum(static_cast<unsigned char>(c))) {
        token += c;
      } else if (!token.empty()) {
        tokens.push_back(token);
        token.clear();
      }
    }
    const char* preset = nullptr;
    for (const std::string& t : tokens) {
      if (t == "fr1" || t == "freiburg1") preset = "tum_fr1";
      if (t == "fr2" || t == "freiburg2") preset = "tum_fr2";
      if (t == "fr3" || t == "freiburg3") preset = "tum_fr3";
      if (t == "icl" || t == "iclnuim") preset = "icl_nuim";
      if (preset) break;
    }
    if (!preset &&
        (name.find("7scenes") != std::string::npos || name.find("7-scenes") != std::string::npos ||
         name.find("7_scenes") != std::string::npos ||
         name.find("seven_scenes") != std::string::npos))
      preset = "seven_scenes";
    if (preset) {
      *matched_name = candidate.filename().string();
      return &camera_preset(preset);
    }
  }
  return nullptr;
}

std::string preset_names() {
  std::string names;
  for (const CameraPreset& p : camera_presets()) {
    if (!names.empty()) names += ", ";
    names += p.name;
  }
  return names;
}

}  // namespace

// ---- FileDataset -----------------------------------------------------------------------------

FileDataset::FileDataset(DatasetInfo info, std::vector<FrameFiles> frames, DepthDecoding decoding)
    : info_(std::move(info)), frames_(std::move(frames)), decoding_(decoding) {
  if (frames_.empty()) fail(ErrorCode::InvalidData, "{}: the dataset has no frames", info_.source);
  truncate(0);  // fills the frame-derived fields of info_
  if (info_.undistorted)
    undistorter_ = std::make_unique<Undistorter>(info_.rig.depth_camera, info_.distortion);
}

void FileDataset::truncate(std::size_t max_frames) {
  if (max_frames > 0 && frames_.size() > max_frames) frames_.resize(max_frames);
  info_.frame_count = frames_.size();
  info_.first_timestamp_s = frames_.front().timestamp_s;
  info_.has_color = !frames_.front().color.empty();
  info_.ground_truth_count = static_cast<std::size_t>(std::count_if(
      frames_.begin(), frames_.end(),
      [](const FrameFiles& f) { return f.T_wc_gt.has_value() || !f.pose_file.empty(); }));
  info_.has_ground_truth = info_.ground_truth_count > 0;
  info_.median_frame_step_s = 0;
  if (info_.timestamps_recorded && frames_.size() >= 2) {
    std::vector<double> steps;
    for (std::size_t i = 1; i < frames_.size(); ++i)
      steps.push_back(frames_[i].timestamp_s - frames_[i - 1].timestamp_s);
    info_.median_frame_step_s = median_of(steps);
  }
}

const FrameFiles& FileDataset::frame(std::size_t index) const {
  if (index >= frames_.size())
    fail(ErrorCode::InvalidArgument, "{}: frame index {} is out of range (the dataset has {})",
         info_.source, index, frames_.size());
  return frames_[index];
}

DepthImage FileDataset::read_depth(std::size_t index) const {
  const FrameFiles& f = frame(index);
  const Image<uint16_t> raw = read_depth16(f.depth);
  check_size(f.depth, "depth", raw.width(), raw.height(), info_.rig.depth_camera,
             info_.intrinsics_source);
  DepthImage depth =
      depth_to_metres(raw, decoding_.scale, decoding_.invalid_raw, decoding_.offset_m);
  if (decoding_.offset_m < 0) {  // a negative affine offset can push small raw values below 0
    float* d = depth.data();
    for (std::size_t i = 0; i < depth.size(); ++i) d[i] = d[i] > 0.0f ? d[i] : 0.0f;
  }
  return depth;
}

RgbdFrame FileDataset::read(std::size_t index) {
  const FrameFiles& f = frame(index);
  RgbdFrame out;
  out.index = index;
  out.timestamp_s = f.timestamp_s;
  out.depth_m = read_depth(index);
  if (undistorter_) out.depth_m = undistorter_->depth(out.depth_m);
  if (!f.color.empty()) {
    out.color = read_color(f.color);
    check_size(f.color, "colour", out.color.width(), out.color.height(), info_.rig.color_camera,
               info_.intrinsics_source);
    // Registered colour shares the depth camera and its distortion.
    if (undistorter_ && info_.rig.color_registered()) out.color = undistorter_->color(out.color);
  }
  if (f.T_wc_gt) {
    out.T_wc_gt = f.T_wc_gt;
  } else if (!f.pose_file.empty()) {
    out.T_wc_gt = read_pose_matrix(f.pose_file);
  }
  return out;
}

// ---- calibration -----------------------------------------------------------------------------

void Calibration::apply_to(DatasetInfo& info, bool undistort) const {
  info.rig.depth_camera = camera;
  info.rig.color_camera = camera;
  info.intrinsics_source = intrinsics_source;
  info.distortion = distortion;
  info.undistorted = undistort && !distortion.none();
  info.rig.depth_scale = depth_scale;
  info.depth_scale_source = depth_scale_source;
  if (depth_noise) info.rig.depth_noise = *depth_noise;
}

Calibration resolve_calibration(const fs::path& dir, const DatasetParams& params,
                                const LayoutDefaults& defaults) {
  Calibration c;
  std::optional<IntrinsicsFile> explicit_file;
  if (!params.intrinsics_path.empty()) explicit_file = read_intrinsics_json(params.intrinsics_path);
  const CameraPreset* explicit_preset =
      params.preset.empty() ? nullptr : &camera_preset(params.preset);

  // The folder's own intrinsics.json is read only when an explicit choice leaves something
  // open, so a broken file there does not stop a user who overrides it.
  const fs::path folder_json = dir / "intrinsics.json";
  std::error_code ec;
  const bool has_folder_json = fs::is_regular_file(folder_json, ec);
  std::optional<IntrinsicsFile> folder_file;
  auto load_folder_file = [&]() -> const IntrinsicsFile* {
    if (!has_folder_json) return nullptr;
    if (!folder_file) folder_file = read_intrinsics_json(folder_json);
    return &*folder_file;
  };

  // The camera, its distortion and (from an intrinsics file) the depth's noise model come
  // together from one source.
  auto take = [&c](const auto& from, std::string source) {
    c.camera = from.camera;
    c.distortion = from.distortion;
    if constexpr (requires { from.depth_noise; }) c.depth_noise = from.depth_noise;
    c.intrinsics_source = std::move(source);
  };
  const CameraPreset* guessed = nullptr;
  if (explicit_file) {
    take(*explicit_file, fmt::format("{} (given)", params.intrinsics_path.string()));
  } else if (explicit_preset) {
    take(*explicit_preset, fmt::format("preset {} (given)", explicit_preset->name));
  } else if (const IntrinsicsFile* f = load_folder_file()) {
    take(*f, folder_json.string());
  } else if (defaults.preset) {
    take(*defaults.preset,
         defaults.preset_is_file
             ? std::string(defaults.preset->name)
             : fmt::format("preset {} ({} default)", defaults.preset->name, defaults.layout_name));
  } else {
    std::string matched;
    if (defaults.guess_from_folder_name) guessed = guess_preset(dir, &matched);
    if (!guessed)
      fail(ErrorCode::InvalidArgument,
           "{}: no intrinsics.json and the camera cannot be guessed from the folder name; give a "
           "camera preset (--preset, one of: {}) or an intrinsics file (--intrinsics FILE)",
           dir.string(), preset_names());
    take(*guessed,
         fmt::format("preset {}, guessed from the folder name '{}'", guessed->name, matched));
  }

  if (params.depth_scale > 0) {
    c.depth_scale = params.depth_scale;
    c.depth_scale_source = "given";
  } else if (explicit_file && explicit_file->depth_scale > 0) {
    c.depth_scale = explicit_file->depth_scale;
    c.depth_scale_source = fmt::format("{} (given)", params.intrinsics_path.string());
  } else if (explicit_preset) {
    c.depth_scale = explicit_preset->depth_scale;
    c.depth_scale_source = fmt::format("preset {} (given)", explicit_preset->name);
  } else if (const IntrinsicsFile* f = load_folder_file(); f && f->depth_scale > 0) {
    c.depth_scale = f->depth_scale;
    c.depth_scale_source = folder_json.string();
  } else if (defaults.preset) {
    c.depth_scale = defaults.preset->depth_scale;
    c.depth_scale_source =
        defaults.preset_is_file
            ? fmt::format("{} default", defaults.layout_name)
            : fmt::format("preset {} ({} default)", defaults.preset->name, defaults.layout_name);
  } else if (guessed) {
    c.depth_scale = guessed->depth_scale;
    c.depth_scale_source = fmt::format("preset {}, guessed from the folder name", guessed->name);
  } else if (defaults.depth_scale > 0) {
    c.depth_scale = defaults.depth_scale;
    c.depth_scale_source = defaults.depth_scale_source;
  } else {
    fail(ErrorCode::InvalidArgument, "{}: no depth scale known; give one with --depth-scale",
         dir.string());
  }
  return c;
}

// ---- pose files ------------------------------------------------------------------------------

Pose read_pose_matrix(const fs::path& path) {
  const std::vector<TextLine> lines = read_text_lines(path);
  std::vector<double> v;
  v.reserve(16);
  for (const TextLine& line : lines)
    for (std::size_t i = 0; i < line.fields.size(); ++i) {
      if (v.size() == 16)
        fail(ErrorCode::InvalidData,
             "{}:{}: more than 16 numbers; expected a 4x4 camera-to-world matrix", path.string(),
             line.number);
      v.push_back(parse_double(path, line, i, "matrix entry"));
    }
  if (v.size() != 16)
    fail(ErrorCode::InvalidData,
         "{}: expected a 4x4 camera-to-world matrix (16 numbers, row-major), found {} numbers",
         path.string(), v.size());
  return pose_from_row_major(v, path.string());
}

Pose pose_from_row_major(const std::vector<double>& v, const std::string& where) {
  const Eigen::Matrix4d m =
      Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(v.data());
  if ((m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-6)
    fail(ErrorCode::InvalidData, "{}: last matrix row must be '0 0 0 1', found '{} {} {} {}'",
         where, m(3, 0), m(3, 1), m(3, 2), m(3, 3));
  const Eigen::Matrix3d R = m.topLeftCorner<3, 3>();
  // Stored poses are rounded; anything further than this from a rotation is not a pose.
  const double error = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (error > 1e-3 || R.determinant() < 0)
    fail(ErrorCode::InvalidData,
         "{}: the 3x3 block is not a rotation (|R^T R - I| = {:.2g}, det = {:.3f})", where, error,
         R.determinant());
  Pose T = Pose::Identity();
  T.linear() = Eigen::Quaterniond(R).normalized().toRotationMatrix();
  T.translation() = m.topRightCorner<3, 1>();
  return T;
}

// ---- images and folders ----------------------------------------------------------------------

bool is_depth16_png(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::array<unsigned char, 26> h{};
  if (!in.read(reinterpret_cast<char*>(h.data()), h.size())) return false;
  static constexpr std::array<unsigned char, 8> kSignature = {0x89, 'P',  'N',  'G',
                                                              '\r', '\n', 0x1A, '\n'};
  if (!std::equal(kSignature.begin(), kSignature.end(), h.begin())) return false;
  // IHDR follows the signature: length (4), "IHDR" (4), width (4), height (4), bit depth, type.
  return h[12] == 'I' && h[13] == 'H' && h[14] == 'D' && h[15] == 'R' && h[24] == 16 && h[25] == 0;
}

namespace {

bool is_seven_scenes_depth_name(const std::string& name) {
  static constexpr std::string_view kPrefix = "frame-", kSuffix = ".depth.png";
  if (name.size() <= kPrefix.size() + kSuffix.size() || !name.starts_with(kPrefix) ||
      !name.ends_with(kSuffix))
    return false;
  const auto digits =
      std::string_view(name).substr(kPrefix.size(), name.size() - kPrefix.size() - kSuffix.size());
  return std::all_of(digits.begin(), digits.end(),
                     [](char c) { return std::isdigit(static_cast<unsigned char>(c)); });
}

bool has_seven_scenes_frames(const fs::path& dir) {
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec))
    if (is_seven_scenes_depth_name(it->path().filename().string())) return true;
  return false;
}

/// NN of `seq-NN` (also `seq-N`), or -1.
long sequence_number(const std::string& name) {
  if (!name.starts_with("seq-") || name.size() == 4) return -1;
  long n = 0;
  for (std::size_t i = 4; i < name.size(); ++i) {
    if (!std::isdigit(static_cast<unsigned char>(name[i]))) return -1;
    n = n * 10 + (name[i] - '0');
  }
  return n;
}

}  // namespace

std::vector<fs::path> seven_scenes_sequences(const fs::path& dir) {
  if (has_seven_scenes_frames(dir)) return {dir};
  std::vector<std::pair<long, fs::path>> found;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const long n = sequence_number(it->path().filename().string());
    if (n >= 0 && it->is_directory(ec) && has_seven_scenes_frames(it->path()))
      found.emplace_back(n, it->path());
  }
  std::sort(found.begin(), found.end());
  std::vector<fs::path> out;
  out.reserve(found.size());
  for (auto& [n, path] : found) out.push_back(std::move(path));
  return out;
}

}  // namespace hivox::detail

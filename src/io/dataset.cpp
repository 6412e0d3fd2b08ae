#include "hivox/io/dataset.h"
#include "hivox/synth/synthetic_dataset.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <numeric>

#include <fmt/format.h>

#include "hivox/core/error.h"
#include "hivox/core/log.h"
#include "io/dataset_internal.h"

namespace hivox {

namespace fs = std::filesystem;

namespace {

constexpr PinholeCamera vga(float fx, float fy, float cx, float cy) {
  return PinholeCamera{fx, fy, cx, cy, 640, 480};
}

// Published calibrations: TUM RGB-D "file formats" page (fr1-3 with their lens distortion, the
// default), ICL-NUIM (its negative fy mirrors y), 7-Scenes (depth camera), Redwood (PrimeSense
// default, as in Open3D).
constexpr std::array<CameraPreset, 7> kPresets = {{
    {"tum_fr1",
     vga(517.3f, 516.5f, 318.6f, 255.3f),
     5000,
     "TUM RGB-D Freiburg 1 (Kinect)",
     {0.2624f, -0.9531f, -0.0054f, 0.0026f, 1.1633f}},
    {"tum_fr2",
     vga(520.9f, 521.0f, 325.1f, 249.7f),
     5000,
     "TUM RGB-D Freiburg 2 (Kinect)",
     {0.2312f, -0.7849f, -0.0033f, -0.0001f, 0.9172f}},
    {"tum_fr3", vga(535.4f, 539.2f, 320.1f, 247.6f), 5000, "TUM RGB-D Freiburg 3 (Xtion)"},
    {"tum_default", vga(525.0f, 525.0f, 319.5f, 239.5f), 5000, "TUM ROS default (Kinect)"},
    {"icl_nuim", vga(481.20f, -480.00f, 319.50f, 239.50f), 5000, "ICL-NUIM (negative fy)"},
    {"seven_scenes", vga(585.0f, 585.0f, 320.0f, 240.0f), 1000, "Microsoft 7-Scenes (depth mm)"},
    {"redwood", vga(525.0f, 525.0f, 319.5f, 239.5f), 1000, "Redwood / PrimeSense (depth mm)"},
}};

/// Frames sampled for statistics: up to `count` indices spread evenly over [0, n).
std::vector<std::size_t> spread_indices(std::size_t n, std::size_t count) {
  std::vector<std::size_t> out;
  if (n == 0) return out;
  if (n <= count) {
    out.resize(n);
    std::iota(out.begin(), out.end(), std::size_t{0});
    return out;
  }
  for (std::size_t k = 0; k < count; ++k)
    out.push_back(static_cast<std::size_t>(
        std::llround(static_cast<double>(k) * static_cast<double>(n - 1) / (count - 1))));
  return out;
}

void append_valid(const DepthImage& depth, std::vector<float>* values) {
  const float* d = depth.data();
  for (std::size_t i = 0; i < depth.size(); ++i)
    if (d[i] > 0.0f) values->push_back(d[i]);
}

std::string list_frames(const std::vector<std::size_t>& indices) {
  std::string s;
  for (std::size_t i : indices) s += (s.empty() ? "" : ", ") + std::to_string(i);
  return s;
}

/// The classic wrong-scale mistake: read a few of the first frames and warn when the median
/// valid depth is not something an RGB-D camera sees (0.1-10 m).
void check_depth_scale(detail::FileDataset& dataset) {
  DatasetInfo& info = dataset.mutable_info();
  const auto indices = spread_indices(std::min<std::size_t>(dataset.size(), 30), 5);
  std::vector<float> values;
  try {
    for (std::size_t i : indices) append_valid(dataset.read_depth(i), &values);
  } catch (const Error& e) {
    info.warnings.push_back(fmt::format("depth-scale check skipped: {}", e.what()));
    log::warn("{}", info.warnings.back());
    return;
  }
  if (values.empty()) {
    info.warnings.push_back(
        fmt::format("frames {} have no valid depth pixel at all", list_frames(indices)));
    log::warn("{}", info.warnings.back());
    return;
  }
  const double median_m = detail::median_of(values);
  if (median_m >= 0.1 && median_m <= 10.0) return;
  // Suggest the common scale that brings the median nearest to a typical 2 m, else the scale
  // that puts it at 2 m.
  const double raw_median = median_m * info.rig.depth_scale;
  double suggested = 0;
  for (double candidate : {1000.0, 5000.0}) {
    const double d = raw_median / candidate;
    if (d >= 0.1 && d <= 10.0 &&
        (suggested == 0 ||
         std::abs(std::log(d / 2.0)) < std::abs(std::log(raw_median / suggested / 2.0))))
      suggested = candidate;
  }
  if (suggested == 0) suggested = std::stod(fmt::format("{:.3g}", raw_median / 2.0));
  info.warnings.push_back(fmt::format(
      "median valid depth of frames {} is {:.3g} m with depth scale {:g} ({}), outside the "
      "plausible 0.1-10 m: the depth scale is probably wrong; {:g} would give {:.2f} m "
      "(--depth-scale {:g})",
      list_frames(indices), median_m, info.rig.depth_scale, info.depth_scale_source, suggested,
      raw_median / suggested, suggested));
  log::warn("{}", info.warnings.back());
}

/// Frames far apart in time: tracking against the model (ICP from the last pose, extrapolated)
/// expects the small motion between the frames of a camera's 15-30 frames/s, and on keyframes
/// taken every half second it can settle on a wrong pose that fits the model well (on TUM's
/// fr3/cabinet keyframes, 0.67 s apart, 55 of 58 frames tracked "good" at 35 cm ATE). Warns
/// where the recorded timestamps step by more than this, seconds (slower than ~7 frames/s).
constexpr double kLargeFrameStepS = 0.15;

void check_frame_steps(detail::FileDataset& dataset) {
  DatasetInfo& info = dataset.mutable_info();
  if (info.median_frame_step_s <= kLargeFrameStepS) return;
  info.warnings.push_back(fmt::format(
      "frames are {:.2f} s apart (the median step of their timestamps, {:.1f} frames/s): "
      "tracking (--poses icp, the default) expects the small motion between the frames of a "
      "camera's 15-30 frames/s and can misplace frames this far apart without noticing; "
      "ground-truth or given poses (--poses gt, --poses FILE) are not affected",
      info.median_frame_step_s, 1.0 / info.median_frame_step_s));
  log::warn("{}", info.warnings.back());
}

}  // namespace

// ---- parameters and presets ------------------------------------------------------------------

void DatasetParams::validate() const {
  if (!std::isfinite(depth_scale) || depth_scale < 0)
    fail(ErrorCode::InvalidArgument,
         "depth_scale must be > 0 raw units per metre (e.g. 5000 for TUM, 1000 for mm), or 0 to "
         "take it from the dataset; got {}",
         depth_scale);
  if (!preset.empty()) camera_preset(preset);  // throws listing the known names
  if (!preset.empty() && !intrinsics_path.empty())
    fail(ErrorCode::InvalidArgument,
         "give either a camera preset ('{}') or an intrinsics file ('{}'), not both", preset,
         intrinsics_path.string());
}

std::string DatasetParams::to_string() const {
  return fmt::format("preset={} depth_scale={} intrinsics={} max_frames={} undistort={}",
                     preset.empty() ? "(none)" : preset,
                     depth_scale > 0 ? fmt::format("{:g}", depth_scale) : "auto",
                     intrinsics_path.empty() ? "(dataset)" : intrinsics_path.string(),
                     max_frames > 0 ? std::to_string(max_frames) : "all", undistort);
}

std::span<const CameraPreset> camera_presets() {
  return kPresets;
}

const CameraPreset& camera_preset(std::string_view name) {
  for (const CameraPreset& p : kPresets)
    if (p.name == name) return p;
  std::string names;
  for (const CameraPreset& p : kPresets) names += (names.empty() ? "" : ", ") + std::string(p.name);
  fail(ErrorCode::InvalidArgument, "unknown camera preset '{}'; known presets: {}", name, names);
}

// ---- layouts ---------------------------------------------------------------------------------

DatasetLayout detect_layout(const fs::path& dir) {
  std::error_code ec;
  if (!fs::exists(dir, ec))
    fail(ErrorCode::Io, "{}: dataset directory does not exist", dir.string());
  if (!fs::is_directory(dir, ec))
    fail(ErrorCode::Io, "{}: is not a directory (give the dataset folder)", dir.string());
  if (fs::is_regular_file(dir / "associations.txt", ec) ||
      fs::is_regular_file(dir / "depth.txt", ec))
    return DatasetLayout::Tum;
  if (fs::is_regular_file(dir / "calib.txt", ec)) return DatasetLayout::InfiniTam;
  if (!detail::seven_scenes_sequences(dir).empty()) return DatasetLayout::SevenScenes;
  if (detail::is_replica_layout(dir)) return DatasetLayout::Replica;
  if (detail::is_scannet_layout(dir)) return DatasetLayout::ScanNet;
  if (detail::is_image_folder_layout(dir))
    return fs::is_regular_file(dir / "camera_intrinsic.json", ec) ? DatasetLayout::Open3d
                                                                  : DatasetLayout::ImageFolder;
  fail(ErrorCode::InvalidData,
       "{}: not a dataset layout hivox knows; looked for associations.txt or depth.txt (+ "
       "rgb.txt) (TUM), calib.txt with numbered frames (InfiniTAM), "
       "seq-NN/frame-NNNNNN.depth.png or frame-NNNNNN.depth.png (7-Scenes), a depth/ folder "
       "(Open3D with camera_intrinsic.json, else an image folder), 16-bit depth PNGs, results/ "
       "with traj.txt (Replica), and depth/ with pose/ and intrinsic/ (ScanNet)",
       dir.string());
}

std::unique_ptr<DatasetReader> open_dataset(const std::string& spec, const DatasetParams& params) {
  if (is_synthetic_spec(spec)) {
    // Built-in scenes are rendered, not read: calibration options do not apply.
    if (!params.preset.empty() || params.depth_scale != 0 || !params.intrinsics_path.empty())
      fail(ErrorCode::InvalidArgument,
           "'{}': --preset, --depth-scale and --intrinsics do not apply to synthetic scenes; set "
           "the camera in the spec (e.g. synthetic:desk?width=320&height=240)",
           spec);
    SyntheticParams synthetic = parse_synthetic_spec(spec);
    if (params.max_frames > 0) synthetic.frames = std::min(synthetic.frames, params.max_frames);
    return std::make_unique<SyntheticDataset>(synthetic);
  }
  if (spec.empty()) fail(ErrorCode::InvalidArgument, "no dataset given (empty path)");
  params.validate();
  const fs::path dir(spec);
  std::unique_ptr<detail::FileDataset> dataset;
  switch (detect_layout(dir)) {
    case DatasetLayout::Tum:
      dataset = detail::open_tum(dir, params);
      break;
    case DatasetLayout::SevenScenes:
      dataset = detail::open_seven_scenes(dir, params);
      break;
    case DatasetLayout::InfiniTam:
      dataset = detail::open_infinitam(dir, params);
      break;
    case DatasetLayout::Open3d:
    case DatasetLayout::ImageFolder:
      dataset = detail::open_image_folders(dir, params);
      break;
    case DatasetLayout::Replica:
      dataset = detail::open_replica(dir, params);
      break;
    case DatasetLayout::ScanNet:
      dataset = detail::open_scannet(dir, params);
      break;
    case DatasetLayout::Synthetic:
      fail(ErrorCode::Unsupported, "'{}': synthetic scenes are not file datasets", spec);
  }
  DatasetInfo& info = dataset->mutable_info();
  if (info.layout_reason.empty())
    info.layout_reason =
        info.layout == DatasetLayout::Tum
            ? (fs::exists(dir / "associations.txt") ? "associations.txt" : "depth.txt")
        : info.layout == DatasetLayout::InfiniTam ? "calib.txt"
                                                  : "frame-NNNNNN.depth.png files";
  dataset->truncate(params.max_frames);
  check_depth_scale(*dataset);
  check_frame_steps(*dataset);
  return dataset;
}

// ---- association -----------------------------------------------------------------------------

std::vector<std::pair<std::size_t, std::size_t>> associate_timestamps(
    const std::vector<double>& t_a_s, const std::vector<double>& t_b_s, double max_dt_s) {
  std::vector<std::size_t> order_b(t_b_s.size());
  std::iota(order_b.begin(), order_b.end(), std::size_t{0});
  std::stable_sort(order_b.begin(), order_b.end(),
                   [&](std::size_t x, std::size_t y) { return t_b_s[x] < t_b_s[y]; });
  struct Candidate {
    double dt, t_a, t_b;
    std::size_t a, b;
  };
  std::vector<Candidate> candidates;
  for (std::size_t a = 0; a < t_a_s.size(); ++a) {
    const double t = t_a_s[a];
    auto it = std::lower_bound(order_b.begin(), order_b.end(), t - max_dt_s,
                               [&](std::size_t b, double v) { return t_b_s[b] < v; });
    for (; it != order_b.end() && t_b_s[*it] <= t + max_dt_s; ++it) {
      const double dt = std::abs(t - t_b_s[*it]);
      if (dt <= max_dt_s) candidates.push_back({dt, t, t_b_s[*it], a, *it});
    }
  }
  // associate.py sorts (|dt|, a, b) tuples and takes them greedily.
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& x, const Candidate& y) {
    return std::tie(x.dt, x.t_a, x.t_b, x.a, x.b) < std::tie(y.dt, y.t_a, y.t_b, y.a, y.b);
  });
  std::vector<char> used_a(t_a_s.size(), 0), used_b(t_b_s.size(), 0);
  std::vector<std::pair<std::size_t, std::size_t>> matches;
  for (const Candidate& c : candidates) {
    if (used_a[c.a] || used_b[c.b]) continue;
    used_a[c.a] = used_b[c.b] = 1;
    matches.emplace_back(c.a, c.b);
  }
  std::sort(matches.begin(), matches.end(), [&](const auto& x, const auto& y) {
    return std::tie(t_b_s[x.second], t_a_s[x.first]) < std::tie(t_b_s[y.second], t_a_s[y.first]);
  });
  return matches;
}

// ---- description -----------------------------------------------------------------------------

std::string describe_dataset(DatasetReader& reader) {
  const DatasetInfo& info = reader.info();
  std::string out;
  auto line = [&out](std::string_view key, const std::string& value) {
    out += fmt::format("{:<16}{}\n", key.empty() ? std::string() : fmt::format("{}:", key), value);
  };
  line("dataset", info.source);
  line("layout", info.layout_reason.empty()
                     ? std::string(to_string(info.layout))
                     : fmt::format("{} (found: {})", to_string(info.layout), info.layout_reason));
  line("frames", std::to_string(info.frame_count));
  line("resolution",
       fmt::format("{}x{}", info.rig.depth_camera.width, info.rig.depth_camera.height));
  line("intrinsics",
       fmt::format("{}  [{}]", info.rig.depth_camera.to_string(), info.intrinsics_source));
  if (!info.distortion.none())
    line("distortion",
         fmt::format("{}  ({})", info.distortion.to_string(),
                     info.undistorted ? "removed from every frame as it is read" : "kept"));
  const PinholeCamera& cc = info.rig.color_camera;
  if (info.has_color && !info.rig.color_registered()) {
    line("colour camera", cc.to_string());
    const Eigen::Vector3d t = info.rig.T_color_depth.translation();
    line("T_color_depth",
         fmt::format("translation ({:.4f}, {:.4f}, {:.4f}) m, rotation {:.3f} deg", t.x(), t.y(),
                     t.z(), rotation_angle_rad(info.rig.T_color_depth) * 180.0 / std::numbers::pi));
  }
  line("depth scale", info.rig.depth_scale > 0
                          ? fmt::format("{:g} raw units per metre  [{}]", info.rig.depth_scale,
                                        info.depth_scale_source)
                          : "none (depth is metric)");
  const SensorNoise& n = info.rig.depth_noise;
  line("depth noise",
       n.sigma_m(3.0f) == 0.0f
           ? std::string("none (rendered depth: the refinement splits on any detail)")
           : fmt::format("sigma {:.1f} mm at 1 m, {:.1f} mm at 3 m (Kinect-class "
                         "unless intrinsics.json's depth_noise says otherwise)",
                         1e3 * n.sigma_m(1.0f), 1e3 * n.sigma_m(3.0f)));

  const auto indices = spread_indices(reader.size(), 5);
  std::vector<float> values;
  std::size_t pixels = 0;
  for (std::size_t i : indices) {
    const RgbdFrame frame = reader.read(i);
    append_valid(frame.depth_m, &values);
    pixels += frame.depth_m.size();
  }
  if (values.empty()) {
    line("depth range", fmt::format("no valid depth in frames {}", list_frames(indices)));
  } else {
    const auto [lo, hi] = std::minmax_element(values.begin(), values.end());
    const float min_m = *lo, max_m = *hi;
    const float median_m = detail::median_of(values);
    line("depth range",
         fmt::format("{:.3f} / {:.3f} / {:.3f} m (min / median / max valid; {:.0f}% of pixels "
                     "valid; frames {})",
                     min_m, median_m, max_m, 100.0 * values.size() / pixels, list_frames(indices)));
  }
  line("colour", info.has_color ? fmt::format("yes, {}x{}", cc.width, cc.height) : "no");
  if (!info.has_ground_truth)
    line("ground truth", "no");
  else if (info.ground_truth_count > 0)
    line("ground truth", fmt::format("yes, {} of {} frames have a pose", info.ground_truth_count,
                                     info.frame_count));
  else
    line("ground truth", "yes");
  line("first time", fmt::format("{:.6f} s", info.first_timestamp_s));
  if (info.median_frame_step_s > 0)
    line("frame step", fmt::format("{:.3f} s median ({:.1f} frames/s)", info.median_frame_step_s,
                                   1.0 / info.median_frame_step_s));
  if (info.warnings.empty()) {
    line("warnings", "none");
  } else {
    for (std::size_t i = 0; i < info.warnings.size(); ++i)
      line(i == 0 ? "warnings" : "", "- " + info.warnings[i]);
  }
  return out;
}

}  // namespace hivox

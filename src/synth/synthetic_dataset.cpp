#include "hivox/synth/synthetic_dataset.h"

#include <algorithm>
#include <charconv>
#include <cmath>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "hivox/core/error.h"

namespace hivox {

namespace {

constexpr std::string_view kPrefix = "synthetic:";
constexpr std::string_view kKeys = "frames, noise, width, height, seed, max_depth, fps";

template <typename T>
T parse_number(std::string_view spec, std::string_view key, std::string_view value) {
  T out{};
  const auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), out);
  if (ec != std::errc() || end != value.data() + value.size() || value.empty())
    fail(ErrorCode::InvalidArgument, "{}: '{}' is not a valid value for '{}'", spec, value, key);
  return out;
}

}  // namespace

PinholeCamera SyntheticParams::effective_camera() const {
  if (camera) return *camera;
  PinholeCamera c;
  c.fx = c.fy = static_cast<float>(525.0 * width / 640.0);
  c.cx = static_cast<float>(0.5 * (width - 1));
  c.cy = static_cast<float>(0.5 * (height - 1));
  c.width = width;
  c.height = height;
  return c;
}

void SyntheticParams::validate() const {
  const auto names = scene_names();
  if (std::find(names.begin(), names.end(), scene) == names.end())
    fail(ErrorCode::InvalidArgument, "synthetic: unknown scene '{}'; valid names: {}", scene,
         fmt::join(names, ", "));
  if (frames == 0) fail(ErrorCode::InvalidArgument, "synthetic: frames must be >= 1, got 0");
  if (width <= 0 || height <= 0 || width > 16384 || height > 16384)
    fail(ErrorCode::InvalidArgument, "synthetic: width x height must be in 1..16384, got {}x{}",
         width, height);
  if (camera) {
    camera->validate("synthetic: camera");
    if (camera->width != width || camera->height != height)
      fail(ErrorCode::InvalidArgument,
           "synthetic: camera is {}x{} but width x height is {}x{}; they must agree", camera->width,
           camera->height, width, height);
  }
  noise.validate();
  if (!std::isfinite(max_depth_m) || max_depth_m <= 0.0)
    fail(ErrorCode::InvalidArgument, "synthetic: max_depth_m must be > 0, got {}", max_depth_m);
  if (!std::isfinite(fps) || fps <= 0.0)
    fail(ErrorCode::InvalidArgument, "synthetic: fps must be > 0, got {}", fps);
}

std::string SyntheticParams::to_string() const {
  return fmt::format("scene={} frames={} size={}x{} camera=[{}] max_depth={} m fps={} noise=[{}]",
                     scene, frames, width, height, effective_camera().to_string(), max_depth_m, fps,
                     noise.to_string());
}

bool is_synthetic_spec(std::string_view spec) {
  return spec.substr(0, kPrefix.size()) == kPrefix;
}

SyntheticParams parse_synthetic_spec(std::string_view spec) {
  if (!is_synthetic_spec(spec))
    fail(ErrorCode::InvalidArgument,
         "'{}' is not a synthetic dataset (expected {}NAME[?KEY=VALUE&...])", spec, kPrefix);
  std::string_view rest = spec.substr(kPrefix.size());
  const std::size_t q = rest.find('?');
  const std::string_view name = rest.substr(0, q);
  SyntheticParams params;
  if (name.empty())
    fail(ErrorCode::InvalidArgument, "{}: missing scene name; valid names: {}", spec,
         fmt::join(scene_names(), ", "));
  params.scene = std::string(name);

  std::optional<int> width, height;
  std::optional<std::uint64_t> seed;
  std::string_view query = q == std::string_view::npos ? std::string_view{} : rest.substr(q + 1);
  while (!query.empty()) {
    const std::size_t amp = query.find('&');
    const std::string_view item = query.substr(0, amp);
    query = amp == std::string_view::npos ? std::string_view{} : query.substr(amp + 1);
    if (item.empty()) continue;
    const std::size_t eq = item.find('=');
    if (eq == std::string_view::npos)
      fail(ErrorCode::InvalidArgument, "{}: '{}' is not KEY=VALUE (keys: {})", spec, item, kKeys);
    const std::string_view key = item.substr(0, eq), value = item.substr(eq + 1);
    if (key == "frames") {
      params.frames = parse_number<std::size_t>(spec, key, value);
    } else if (key == "noise") {
      params.noise = noise_preset(value);
    } else if (key == "width") {
      width = parse_number<int>(spec, key, value);
    } else if (key == "height") {
      height = parse_number<int>(spec, key, value);
    } else if (key == "seed") {
      seed = parse_number<std::uint64_t>(spec, key, value);
    } else if (key == "max_depth") {
      params.max_depth_m = parse_number<double>(spec, key, value);
    } else if (key == "fps") {
      params.fps = parse_number<double>(spec, key, value);
    } else {
      fail(ErrorCode::InvalidArgument, "{}: unknown key '{}' (keys: {})", spec, key, kKeys);
    }
  }
  // One of width/height alone keeps the 4:3 aspect of the default.
  if (width && !height) height = static_cast<int>(std::lround(*width * 0.75));
  if (height && !width) width = static_cast<int>(std::lround(*height / 0.75));
  if (width) params.width = *width;
  if (height) params.height = *height;
  if (seed) params.noise.seed = *seed;  // after `noise=`, which resets the parameters
  params.validate();
  return params;
}

SyntheticDataset::SyntheticDataset(SyntheticParams params) : params_(std::move(params)) {
  params_.validate();
  camera_ = params_.effective_camera();
  scene_ = make_scene(params_.scene);
  trajectory_ = make_trajectory(scene_.camera_path(), params_.frames, params_.fps);
  info_.source = std::string(kPrefix) + params_.scene;
  info_.layout = DatasetLayout::Synthetic;
  info_.frame_count = params_.frames;
  info_.rig.depth_camera = camera_;
  info_.rig.color_camera = camera_;
  info_.intrinsics_source =
      params_.camera ? "synthetic (given)" : "synthetic (Kinect-like: 525 px at 640 wide)";
  info_.rig.depth_scale = 0;
  info_.depth_scale_source = "metric (synthetic)";
  info_.has_color = true;
  info_.has_ground_truth = true;
  info_.first_timestamp_s = trajectory_.empty() ? 0.0 : trajectory_.front().timestamp_s;
  info_.rig.depth_noise = params_.noise.sensor_noise();
}

RenderedFrame SyntheticDataset::render_clean(std::size_t index) const {
  if (index >= trajectory_.size())
    fail(ErrorCode::InvalidArgument, "{}: frame {} out of range (0..{})", info_.source, index,
         trajectory_.size() - 1);
  return render(scene_, camera_, trajectory_[index].T_wc, params_.max_depth_m);
}

RgbdFrame SyntheticDataset::read(std::size_t index) {
  RenderedFrame clean = render_clean(index);
  RgbdFrame frame;
  frame.index = index;
  frame.timestamp_s = trajectory_[index].timestamp_s;
  frame.depth_m = apply_noise(clean, camera_, params_.noise, index);
  frame.color = std::move(clean.color);
  frame.T_wc_gt = trajectory_[index].T_wc;
  return frame;
}

}  // namespace hivox

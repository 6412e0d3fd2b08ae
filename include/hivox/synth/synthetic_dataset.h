#pragma once
/// @file
/// A built-in synthetic scene as a `DatasetReader`: frames are rendered on demand along the
/// scene's camera path, with optional Kinect-like noise, and come with exact poses. The scene
/// (exact SDF, normals, labels) and the trajectory stay queryable for tests.
///
/// Spec strings (what `hivox` commands accept where a dataset path goes):
///
///     synthetic:NAME[?KEY=VALUE[&KEY=VALUE...]]
///
/// NAME is a scene (`scene_names()`: room, box, spheres, keyboard, blob, desk). Keys:
/// `frames` (count, default 300), `noise` (`kinect` or `none`, default kinect), `width`,
/// `height` (pixels, default 640x480; one alone keeps 4:3; the camera scales with the width),
/// `seed` (noise seed),
/// `max_depth` (metres, default 10), `fps` (default 30). Example:
/// `synthetic:desk?frames=100&noise=none&width=320&height=240`.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "hivox/core/dataset.h"
#include "hivox/synth/noise.h"
#include "hivox/synth/render.h"
#include "hivox/synth/scene.h"

namespace hivox {

struct SyntheticParams {
  std::string scene = "desk";  ///< one of `scene_names()`
  std::size_t frames = 300;    ///< frames along the (closed) camera path
  int width = 640;             ///< image width, pixels
  int height = 480;            ///< image height, pixels
  /// Intrinsics. Unset (the default): Kinect-like fx = fy = 525 * width / 640 with the principal
  /// point at the image centre (fx = fy = 525, cx = 319.5, cy = 239.5 at 640x480). When set,
  /// its width and height must equal `width` and `height`.
  std::optional<PinholeCamera> camera;
  NoiseParams noise;          ///< Kinect-like by default; `NoiseParams::none()` for clean depth
  double max_depth_m = 10.0;  ///< rendered depth beyond this is invalid (0)
  double fps = 30.0;          ///< frame rate of the timestamps, Hz

  /// The camera used for rendering (`camera` or the default for width x height).
  PinholeCamera effective_camera() const;
  /// Throws `Error(InvalidArgument)` naming the bad field (unknown scene names the valid ones).
  void validate() const;
  std::string to_string() const;
};

/// True when `spec` names a synthetic dataset (starts with `synthetic:`).
bool is_synthetic_spec(std::string_view spec);

/// Parses `synthetic:NAME[?KEY=VALUE&...]` (see the file comment). Throws
/// `Error(InvalidArgument)` naming the bad key or value.
SyntheticParams parse_synthetic_spec(std::string_view spec);

class SyntheticDataset : public DatasetReader {
 public:
  /// Builds the scene and trajectory (validates `params`).
  explicit SyntheticDataset(SyntheticParams params);

  const DatasetInfo& info() const override { return info_; }
  /// Renders frame `index`: depth (noisy per `params().noise`, metres), colour, timestamp and
  /// ground-truth pose. Throws `Error(InvalidArgument)` when `index >= size()`.
  RgbdFrame read(std::size_t index) override;
  bool reads_concurrently() const override { return true; }

  /// The noise-free render of frame `index` (depth, colour, world normals, pose).
  RenderedFrame render_clean(std::size_t index) const;

  const SyntheticParams& params() const { return params_; }
  const PinholeCamera& camera() const { return camera_; }
  /// The scene: exact `sdf()`, `normal()`, `intersect()`, primitive labels, content bounds.
  const SyntheticScene& scene() const { return scene_; }
  /// Ground-truth camera-to-world poses with timestamps, one per frame.
  const std::vector<StampedPose>& trajectory() const { return trajectory_; }

 private:
  SyntheticParams params_;
  PinholeCamera camera_;
  SyntheticScene scene_;
  std::vector<StampedPose> trajectory_;
  DatasetInfo info_;
};

}  // namespace hivox

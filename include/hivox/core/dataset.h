#pragma once
/// @file
/// The one interface every source of RGB-D frames implements (file layouts in `io`, built-in
/// synthetic scenes in `synth`). Frames carry depth in metres (float, 0 = invalid).

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "hivox/core/camera.h"
#include "hivox/core/camera_rig.h"
#include "hivox/core/image.h"
#include "hivox/core/pose.h"

namespace hivox {

enum class DatasetLayout {
  Tum,
  SevenScenes,
  InfiniTam,
  Open3d,       ///< Open3D's reconstruction system / RealSense recorder: depth/, color/,
                ///< camera_intrinsic.json
  ImageFolder,  ///< a folder of depth PNGs (or depth/), optional colour; camera from a preset or
                ///< file
  Replica,      ///< NICE-SLAM-style Replica renders: results/, traj.txt, cam_params.json
  ScanNet,      ///< ScanNet's exported frames: color/, depth/, pose/, intrinsic/
  Synthetic,
};
std::string_view to_string(DatasetLayout layout);

struct DatasetInfo {
  std::string source;  ///< directory, or `synthetic:NAME`
  DatasetLayout layout = DatasetLayout::Tum;
  std::string layout_reason;  ///< what in the folder made it this layout
  std::size_t frame_count = 0;
  /// The cameras, the raw depth units and the depth noise of the sensor that recorded the set.
  CameraRig rig;
  std::string intrinsics_source;  ///< where the intrinsics came from (file, preset name)
  /// Lens distortion of the depth camera (= colour camera when registered) as calibrated.
  LensDistortion distortion;
  /// Frames come with `distortion` removed (depth, and colour when registered); false when the
  /// calibration has none or undistortion was turned off.
  bool undistorted = false;
  std::string depth_scale_source;  ///< file, preset or override that set `rig.depth_scale`
  bool has_color = false;
  bool has_ground_truth = false;
  /// Frames that have a ground-truth pose; 0 when there is none or the source cannot count them
  /// without reading every frame.
  std::size_t ground_truth_count = 0;
  double first_timestamp_s = 0;
  /// The files say when each frame was taken (TUM's lists); other layouts number their frames
  /// and time them at 30 frames/s.
  bool timestamps_recorded = false;
  /// Median step between consecutive frames' timestamps, seconds, where they are recorded; 0
  /// otherwise.
  double median_frame_step_s = 0;
  std::vector<std::string> warnings;  ///< e.g. implausible depth scale; printed by tools
};

struct RgbdFrame {
  std::size_t index = 0;
  double timestamp_s = 0;
  DepthImage depth_m;           ///< metres, 0 = invalid
  ColorImage color;             ///< empty when the dataset has no colour
  std::optional<Pose> T_wc_gt;  ///< ground-truth camera-to-world pose, when known
};

class DatasetReader {
 public:
  virtual ~DatasetReader() = default;
  virtual const DatasetInfo& info() const = 0;
  std::size_t size() const { return info().frame_count; }
  /// Reads frame `index` (< size()). Throws `Error` naming the file when it cannot.
  virtual RgbdFrame read(std::size_t index) = 0;
  /// Whether read() may run on several threads at once, each for another frame (a frame is a
  /// function of its index alone). A run then reads ahead on several threads
  /// (RunParams::read_threads); otherwise on one at most.
  virtual bool reads_concurrently() const { return false; }
};

}  // namespace hivox

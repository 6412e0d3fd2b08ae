#pragma once
// Private to the io module: the one reader class behind every file layout, and the per-layout
// builders that fill it (tum_dataset.cpp, seven_scenes_dataset.cpp, infinitam_dataset.cpp).

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <numeric>
#include <optional>
#include <string>
#include <vector>

#include "hivox/core/dataset.h"
#include "hivox/core/undistort.h"
#include "hivox/io/dataset.h"

namespace hivox::detail {

/// Frames that carry no time (numbered files, 7-Scenes, InfiniTAM) are stamped at this rate:
/// the Kinect and most recorders run at 30 Hz.
constexpr double kFrameRateHz = 30.0;

/// The files of one frame.
struct FrameFiles {
  std::filesystem::path depth;
  std::filesystem::path color;  ///< empty when the dataset has no colour
  double timestamp_s = 0;
  std::optional<Pose> T_wc_gt;      ///< known when the dataset was opened (TUM)
  std::filesystem::path pose_file;  ///< read by `read()` (7-Scenes); empty when none
};

/// How raw depth becomes metres: `raw / scale + offset_m`; 0 and `invalid_raw` are invalid, and
/// so is any result <= 0.
struct DepthDecoding {
  double scale = 0;
  uint16_t invalid_raw = 0;
  double offset_m = 0;
};

/// A dataset of image files on disk. Decodes one frame per `read()`; keeps only file names.
class FileDataset final : public DatasetReader {
 public:
  FileDataset(DatasetInfo info, std::vector<FrameFiles> frames, DepthDecoding decoding);

  const DatasetInfo& info() const override { return info_; }
  RgbdFrame read(std::size_t index) override;
  bool reads_concurrently() const override { return true; }

  /// Depth of frame `index` in metres (no colour, no pose): what the scale check needs.
  DepthImage read_depth(std::size_t index) const;
  DatasetInfo& mutable_info() { return info_; }
  /// Keeps the first `max_frames` frames (0 = all).
  void truncate(std::size_t max_frames);

 private:
  const FrameFiles& frame(std::size_t index) const;

  DatasetInfo info_;
  std::vector<FrameFiles> frames_;
  DepthDecoding decoding_;
  std::unique_ptr<Undistorter> undistorter_;  ///< when `info_.undistorted`
};

/// Intrinsics and depth scale of a registered camera, with where each came from.
struct Calibration {
  PinholeCamera camera;
  LensDistortion distortion;
  std::string intrinsics_source;
  double depth_scale = 0;
  std::string depth_scale_source;
  std::optional<SensorNoise> depth_noise;  ///< from the intrinsics file, when it says

  /// Fills `info`'s camera fields (depth and registered colour camera, distortion, depth scale,
  /// with their sources, the depth noise when known); the distortion is removed from frames when
  /// `undistort` and it has any.
  void apply_to(DatasetInfo& info, bool undistort) const;
};

/// What a layout falls back to when the user and the folder say nothing.
struct LayoutDefaults {
  const char* layout_name = "";
  const CameraPreset* preset = nullptr;  ///< camera of the layout (7-Scenes), or none
  bool guess_from_folder_name = false;   ///< TUM: `freiburg1` / `fr1` in the name -> `tum_fr1`
  double depth_scale = 0;                ///< used when nothing above gives a depth scale
  const char* depth_scale_source = "";
  /// `preset` was read from a file (its `name` is the file's path), e.g. Open3D's
  /// camera_intrinsic.json: sources name the file, and its depth scale is the layout's default.
  bool preset_is_file = false;
};

/// Picks intrinsics and depth scale by priority: `params` (override file, preset, depth scale),
/// then `dir/intrinsics.json`, then the layout's defaults. Throws `Error(InvalidArgument)`
/// asking for a preset or an intrinsics file when nothing gives intrinsics.
Calibration resolve_calibration(const std::filesystem::path& dir, const DatasetParams& params,
                                const LayoutDefaults& defaults);

/// Reads a 4x4 row-major camera-to-world matrix (7-Scenes `frame-NNNNNN.pose.txt`). Errors
/// name the file (and line for a non-number); the rotation is re-orthonormalised.
Pose read_pose_matrix(const std::filesystem::path& path);
/// A camera-to-world pose from 16 numbers (4x4, row-major), checked as read_pose_matrix checks
/// a file; errors start with `where` (a file and line).
Pose pose_from_row_major(const std::vector<double>& v, const std::string& where);

/// True when `path` is a PNG with one 16-bit grey channel (reads the header only).
bool is_depth16_png(const std::filesystem::path& path);

/// Folders of 7-Scenes frames below `dir`: `dir` itself when it holds
/// `frame-NNNNNN.depth.png` files, else its `seq-NN` subfolders that do, sorted by number.
std::vector<std::filesystem::path> seven_scenes_sequences(const std::filesystem::path& dir);

std::unique_ptr<FileDataset> open_tum(const std::filesystem::path& dir,
                                      const DatasetParams& params);
std::unique_ptr<FileDataset> open_seven_scenes(const std::filesystem::path& dir,
                                               const DatasetParams& params);
std::unique_ptr<FileDataset> open_infinitam(const std::filesystem::path& dir,
                                            const DatasetParams& params);
/// Folders of numbered images (folder_dataset.cpp): `depth/` (or 16-bit PNGs in `dir`), colour in
/// `color/`, `rgb/` or `image/`; Open3D's layout when `camera_intrinsic.json` is there.
bool is_image_folder_layout(const std::filesystem::path& dir);
/// The Replica layout of NICE-SLAM-style tools: `results/frameNNNNNN.jpg` and
/// `results/depthNNNNNN.png`, `traj.txt` (a 4x4 camera-to-world matrix per line, row-major),
/// `cam_params.json` in the folder or the one above it.
bool is_replica_layout(const std::filesystem::path& dir);
std::unique_ptr<FileDataset> open_replica(const std::filesystem::path& dir,
                                          const DatasetParams& params);
/// ScanNet's exported frames: `depth/N.png` (mm), `color/N.jpg` (own camera and size),
/// `pose/N.txt` (4x4 camera-to-world; -inf for frames without one), `intrinsic/intrinsic_*.txt`.
bool is_scannet_layout(const std::filesystem::path& dir);
std::unique_ptr<FileDataset> open_scannet(const std::filesystem::path& dir,
                                          const DatasetParams& params);
std::unique_ptr<FileDataset> open_image_folders(const std::filesystem::path& dir,
                                                const DatasetParams& params);

/// The median of `values` (not empty; reordered).
template <typename T>
T median_of(std::vector<T>& values) {
  auto mid = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

}  // namespace hivox::detail

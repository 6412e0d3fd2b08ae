#pragma once
/// @file
/// Opening RGB-D datasets stored as files, behind the `DatasetReader` interface of
/// `hivox/core/dataset.h`. Three layouts are recognised from the directory content:
///
/// - **TUM**: `associations.txt` (`t_rgb rgb_file t_depth depth_file`, either column order), or
///   `rgb.txt` + `depth.txt` associated by nearest timestamp; optional `groundtruth.txt` (TUM
///   trajectory, matched to each depth timestamp within 20 ms) and `intrinsics.json`.
/// - **7-Scenes**: `seq-NN/frame-NNNNNN.{color.png,depth.png,pose.txt}` below a scene folder, or
///   one `seq-NN` folder itself. Depth in millimetres, 65535 = invalid; poses are 4x4
///   camera-to-world matrices.
/// - **InfiniTAM**: `calib.txt` (colour and depth intrinsics, extrinsics, `affine a b` depth
///   line) and numbered frames (`0000.pgm` depth + `0000.ppm` colour, or PNG), in the folder or
///   in its `Frames/` subfolder.
///
/// Frames come out with depth in metres (0 = invalid), colour when the set has it, and the
/// ground-truth camera-to-world pose when one is known.

#include <cstddef>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "hivox/core/camera.h"
#include "hivox/core/dataset.h"

namespace hivox {

/// How to open a dataset. Everything is optional: the defaults read what the folder says.
struct DatasetParams {
  /// Named camera preset (see `camera_presets()`), e.g. `tum_fr1`; empty = none. Overrides
  /// the folder's own calibration (`intrinsics.json`, `calib.txt`, layout default) and sets the
  /// depth scale unless `depth_scale` is given.
  std::string preset;
  /// Raw depth units per metre (e.g. 5000 for TUM); 0 = from the intrinsics file, preset or
  /// layout. Must not be negative.
  double depth_scale = 0;
  /// An `intrinsics.json` to use instead of the folder's own calibration (its `depth_scale`, if
  /// any, too); empty = none. Cannot be combined with `preset`.
  std::filesystem::path intrinsics_path;
  /// Read at most this many frames (the first ones); 0 = all.
  std::size_t max_frames = 0;
  /// Remove the lens distortion of the calibration (if it has any) from every frame as it is
  /// read. Off: frames are used as stored, as if the camera were an ideal pinhole.
  bool undistort = true;

  /// Throws `Error(InvalidArgument)` naming the bad field.
  void validate() const;
  std::string to_string() const;
};

/// A named camera: intrinsics (all 640x480) and the depth scale that goes with the sensor.
struct CameraPreset {
  std::string_view name;
  PinholeCamera camera;
  double depth_scale = 0;  ///< raw depth units per metre
  std::string_view description;
  LensDistortion distortion{};  ///< as published with the intrinsics; none when not given
};

/// All presets: `tum_fr1`, `tum_fr2`, `tum_fr3`, `tum_default`, `icl_nuim` (negative fy),
/// `seven_scenes`, `redwood`.
std::span<const CameraPreset> camera_presets();

/// The preset called `name`; throws `Error(InvalidArgument)` listing the known names.
const CameraPreset& camera_preset(std::string_view name);

/// Recognises the layout of dataset folder `dir`. Throws `Error(Io)` when `dir` is missing or
/// not a directory, and `Error(InvalidData)` listing what it looked for when nothing matches.
DatasetLayout detect_layout(const std::filesystem::path& dir);

/// Opens a dataset folder, detecting its layout. Checks the depth scale on a few of the first
/// frames and adds a line to `info().warnings` (and logs it) when the median valid depth is
/// outside 0.1–10 m, and another where the frames' recorded timestamps lie more than 0.15 s
/// apart (median): too far for tracking against the model. `synthetic:NAME` specs are not
/// served here yet (`Error(Unsupported)`).
std::unique_ptr<DatasetReader> open_dataset(const std::string& spec,
                                            const DatasetParams& params = {});

/// A multi-line, human-readable summary: layout, frame count, resolution, intrinsics and where
/// they came from, depth scale and its source, valid depth range over a few sampled frames,
/// colour, ground-truth poses, first timestamp, the median step between timestamps (where
/// recorded), warnings. Reads a few frames.
std::string describe_dataset(DatasetReader& reader);

/// Associates two time-stamped lists the way TUM's `associate.py` does: all pairs with
/// |t_a - t_b| <= `max_dt_s` are candidates, taken greedily by smallest |dt| (ties: earlier
/// `t_a`, then earlier `t_b`), each element used at most once. Returns index pairs (a, b) sorted
/// by `t_b`. Inputs need not be sorted.
std::vector<std::pair<std::size_t, std::size_t>> associate_timestamps(
    const std::vector<double>& t_a_s, const std::vector<double>& t_b_s, double max_dt_s = 0.02);

}  // namespace hivox

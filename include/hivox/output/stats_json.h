#pragma once
/// @file
/// `stats.json` of a reconstruction run: what was done, how fast, how big.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "hivox/core/device.h"
#include "hivox/pipeline/reconstruction.h"

namespace hivox {

/// Run-level facts the façade does not know.
struct RunInfo {
  std::string dataset;      ///< source (directory or synthetic:NAME)
  std::string pose_source;  ///< "gt", a file name, "icp"
  double wall_s = 0;        ///< the whole loop, reading included
  int threads = 0;
  std::optional<DeviceInfo> gpu;      ///< the GPU a run on a CUDA device ran on
  std::string parameters;             ///< effective parameters, as printed at start
  int64_t frames_fused = -1;          ///< frames integrated (-1: all processed frames)
  int64_t skipped_frames = 0;         ///< frames not integrated (e.g. without a pose)
  int64_t bad_frames = 0;             ///< frames that could not be read (skipped)
  std::string end = "completed";      ///< how the run ended: completed, stopped, bad frame
  std::vector<std::string> warnings;  ///< what makes the result doubtful
  bool unusable = false;              ///< the result is of no use (see RunSummary::unusable)
  std::optional<double> ate_rmse_m;   ///< trajectory error against ground truth, when known
  double depth_scale = 0;             ///< raw depth units per metre used (0: metric depth)
  /// The run's settings as the caller wrote them (RunParams::config_json), embedded as `config`.
  std::string config_json;
};

/// Writes `stats.json` (atomically) with: frames (processed), frames_fused, skipped_frames,
/// bad_frames, end, warnings, unusable, fps (processing, reading excluded), fps_wall (everything),
/// timing_ms (mean per stage: read, upload (to a GPU; 0 on the CPU), track, allocate, integrate,
/// refine, raycast, total),
/// blocks_total, blocks_per_level (finest first), peak_blocks_total, dropped_blocks,
/// bytes_per_voxel, memory_bytes, tracking (good/poor/lost counts), ate_rmse_m (when known),
/// hivox_version, camera (the depth camera's intrinsics), depth_scale, config (when given), gpu
/// (a CUDA run's device: name, memory_bytes, compute_capability, multiprocessors), and
/// per_frame (block counts per level, stage times, tracking quality and ICP numbers).
void write_stats_json(const std::filesystem::path& path, const Reconstruction& reconstruction,
                      const RunInfo& run);

}  // namespace hivox

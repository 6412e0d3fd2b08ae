#pragma once
/// @file
/// A whole reconstruction run as the library does it: a dataset in, a reconstruction and its
/// result files out. The `hivox reconstruct` command, the benchmarks that run sequences and the
/// Python bindings all call `run_reconstruction`; they only parse settings and print.
///
/// The run: poses from ICP tracking, the dataset's ground truth or a trajectory file; the first
/// frame of a tracked run sits at its ground-truth pose when the dataset has one (so that
/// renders and meshes line up with the ground truth), else at the origin (a run that continues a
/// map file tracks its first frame from the map's last pose, where the scan stopped, else from
/// there); a frame whose tracking
/// is lost is not fused and keeps the previous pose (Reconstruction::track_and_integrate); a
/// frame without a pose (given poses) is skipped and counted. At the end, in the output folder:
/// `trajectory.txt`, the renders from the last pose and from an overview pose, `mesh.ply` and
/// `stats.json`; the map file when asked for.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "hivox/core/dataset.h"
#include "hivox/eval/trajectory_eval.h"
#include "hivox/mesh/params.h"
#include "hivox/pipeline/reconstruction.h"

namespace hivox {

/// Where a run's camera poses come from.
enum class PoseSource {
  Icp,          ///< tracked: ICP against the model (the first frame at its true pose if known)
  GroundTruth,  ///< the dataset's ground-truth poses
  File,         ///< a TUM trajectory file, matched to frames by timestamp (within 20 ms)
};

struct PoseSpec {
  PoseSource source = PoseSource::Icp;
  std::filesystem::path file;  ///< with PoseSource::File

  /// "icp", "gt", or the path of a TUM trajectory file.
  static PoseSpec parse(std::string_view text);
  /// As parse takes it.
  std::string to_string() const;
};

/// What a run does with a frame it cannot read (a missing, truncated or corrupt file).
enum class BadFramePolicy {
  Stop,  ///< end the run there, with the results of the frames before it (RunEnd::BadFrame)
  Skip,  ///< warn, count it (RunSummary::frames_bad, stats.json) and go on
};
std::string_view to_string(BadFramePolicy policy);
/// Parses "stop" or "skip"; throws `Error(InvalidArgument)` otherwise.
BadFramePolicy parse_bad_frame_policy(std::string_view name);

struct RunParams {
  ReconstructionParams reconstruction;
  PoseSpec poses;
  std::size_t first_frame = 0;  ///< the dataset's frames from this one (0 = the first)
  std::size_t max_frames = 0;   ///< at most N frames from first_frame; 0 = all
  /// A map file to continue (`.hvx`): its map is loaded and the frames are fused into it, the
  /// refinement's cadence and (when tracking) the pose picked up where it stopped. Its shape
  /// (voxel size, levels, truncation, colour) and maximum weight must equal
  /// `reconstruction`'s, else `Error(InvalidArgument)` names the difference; the capacities are
  /// `reconstruction.map`'s.
  std::filesystem::path map_in;
  /// Where to save the map at the end (also after a stop or a bad frame): a map file that
  /// `map_in`, `hivox mesh`, `hivox render` and `hivox info` read. Empty: not saved.
  std::filesystem::path map_out;
  /// Also write the renders of every N-th frame (`frameNNNNNN_*.png`); 0 = only at the end.
  int render_every = 0;
  MeshParams mesh;
  /// Where the result files go; empty: no files, the run only returns. The files are written
  /// into `<out_dir>.partial-<pid>` beside it and the folder is moved into place when the run
  /// ends (also when it is stopped early), so one run's files never mix with another's.
  std::filesystem::path out_dir;
  /// An `out_dir` that already holds files is refused, unless this is set: then it is replaced
  /// as a whole by the new run's folder when the run ends.
  bool overwrite = false;
  BadFramePolicy on_bad_frame = BadFramePolicy::Stop;
  /// Frames read ahead on threads of their own while the run processes the current one
  /// (decoding overlaps processing; each costs a frame's memory), at most 64. 0: every frame is
  /// read when its turn comes; -1: two per reading thread (see read_plan).
  int read_ahead_frames = -1;
  /// Threads that read ahead, at most 64; several only where the dataset reads concurrently
  /// (DatasetReader::reads_concurrently). 0: the cores the loop leaves free, at most 8 (all but
  /// the driving thread with a GPU; beyond thread_count() on the CPU, so none by default).
  int read_threads = 0;
  /// The run's settings as the caller keeps them (e.g. the CLI's config.json): written as
  /// `config.json` into the output folder and embedded in stats.json; empty = neither.
  std::string config_json;

  /// Throws `Error(InvalidArgument)` naming the bad setting.
  void validate() const;
};

/// How a run reads its frames: `frames` ahead on `threads` threads (0 frames: each in turn), and
/// what the run's parallel loops keep while they read (thread_count() then: ReadAhead shares
/// the cores).
struct ReadPlan {
  int frames = 0;
  int threads = 0;
  int loop_threads = 0;
};
/// What `params.read_ahead_frames` and `read_threads` come to for `reader` on this machine.
ReadPlan read_plan(const RunParams& params, const DatasetReader& reader);

/// How a run ended.
enum class RunEnd {
  Completed,      ///< every frame went through
  StopRequested,  ///< RunCallbacks::stop_requested said so (e.g. an interrupt)
  BadFrame,       ///< a frame could not be read (BadFramePolicy::Stop)
};

/// What a run did, frame by frame and at the end.
struct RunSummary {
  std::size_t frames_total = 0;     ///< frames the run was to go through (max_frames applied)
  std::size_t frames_fused = 0;     ///< integrated into the map
  std::size_t frames_lost = 0;      ///< tracking lost: not fused, previous pose kept
  std::size_t frames_skipped = 0;   ///< without a pose (given poses): not processed
  std::size_t frames_bad = 0;       ///< could not be read and were skipped (BadFramePolicy::Skip)
  std::size_t frames_no_depth = 0;  ///< processed, but without a depth inside the depth range
  RunEnd end = RunEnd::Completed;
  std::string end_reason;  ///< with RunEnd::BadFrame: the frame's error
  /// What makes the result doubtful, one line each (also logged): frames without valid depth,
  /// depths mostly beyond the range, timestamps out of order, tracking lost on most frames, an
  /// empty mesh.
  std::vector<std::string> warnings;
  /// The result is of no use (no frame fused, no valid depth in any frame, an empty mesh, or
  /// tracking lost on most frames); the files are written all the same.
  bool unusable = false;
  double wall_s = 0;             ///< the frame loop, reading included
  double processing_s = 0;       ///< the frame loop's processing (reading excluded)
  std::optional<AteResult> ate;  ///< estimated poses against the ground truth, when both exist
  int64_t mesh_vertices = 0, mesh_triangles = 0;
  double mesh_s = 0;
  double map_load_s = 0, map_save_s = 0;     ///< reading RunParams::map_in, writing map_out
  std::vector<std::filesystem::path> files;  ///< what the run wrote, in order
};

/// A run's outcome: the reconstruction (map, trajectory, per-frame statistics) and the summary.
struct RunResult {
  std::unique_ptr<Reconstruction> reconstruction;
  RunSummary summary;
};

/// What a run tells its caller while it goes on; every member is optional.
struct RunCallbacks {
  /// Before the first frame: the reconstruction (its settings, `describe()`) and the number of
  /// frames to come.
  std::function<void(const Reconstruction&, std::size_t frames_total)> on_start;
  /// After each processed frame: its index in the dataset, its statistics, the reconstruction so
  /// far and the frame itself (e.g. for a live view of the depth).
  std::function<void(std::size_t i, const FrameStats&, const Reconstruction&, const RgbdFrame&)>
      on_frame;
  /// Polled before each frame: true ends the run there; the frames so far are kept and their
  /// results written.
  std::function<bool()> stop_requested;
};

/// A reconstruction on `params.device`: the CPU's, or in builds with -DHIVOX_WITH_CUDA=ON the
/// CUDA loop's (hivox::cuda::make_reconstruction); with `map`, continuing it from `session`.
/// Throws `Error(Unsupported)` naming the device when it cannot run here.
std::unique_ptr<Reconstruction> make_reconstruction(const ReconstructionParams& params,
                                                    const CameraRig& rig,
                                                    std::unique_ptr<VoxelBlockMap> map = nullptr,
                                                    const MapSession& session = {});

/// Runs `reader`'s frames through a reconstruction with `params` and writes the results. Throws
/// `Error` for bad settings (naming them), a pose source the dataset cannot serve, an output
/// folder that holds files (without `overwrite`), a first frame it cannot read, and files it
/// cannot write. A run whose result is of no use returns with `summary.unusable` set.
RunResult run_reconstruction(DatasetReader& reader, const RunParams& params,
                             const RunCallbacks& callbacks = {});

}  // namespace hivox

#pragma once
/// @file
/// The paper's experiments on one dataset (`hivox experiment`): the same sequence reconstructed
/// by several configurations -- by default the fixed finest grid, the fixed coarsest grid and
/// the adaptive hierarchy (paper §VI) -- with the same camera poses, then measured against each
/// other and, where they exist, against ground truth:
///
/// - blocks over the frames, at the end, at the peak, and the saving against the first
///   configuration (the fixed finest grid: Table II, Fig. 6);
/// - time per stage and frames per second;
/// - sdf-error: the mean |SDF| of every map at points sampled on the first configuration's mesh
///   (Table I, `evaluate_sdf_error`);
/// - mesh accuracy and completeness against a reference mesh (`evaluate_mesh`), when one is given;
///   completeness over the part of the reference the frames saw (unoccluded in the depth of up
///   to 60 frames with ground-truth poses), so that a sequence is not incomplete where it never
///   looked;
/// - the trajectory error of tracked runs (one per configuration, ICP), when the dataset has
///   ground-truth poses.
///
/// Files under `out_dir`: `runs/<slug>/` (each run's own result folder: mesh.ply, map.hvx,
/// stats.json, renders), `runs/<slug>-tracked/`, `renders/<slug>_{overview,close}_*.png` (every
/// map from the same two poses: an overview, and the camera pose that sees the most surface
/// detail of 16 spread over the run), `blocks.csv` (blocks per frame and level), `sdf_points.csv`
/// (a subsample of the sdf-error points with each map's |SDF|), `report.json` and `report.md`.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "hivox/core/dataset.h"
#include "hivox/eval/mesh_eval.h"
#include "hivox/eval/sdf_error.h"
#include "hivox/eval/trajectory_eval.h"
#include "hivox/run/runner.h"

namespace hivox {

/// One configuration of an experiment.
struct ExperimentConfig {
  std::string name;  ///< shown in tables and figures ("fixed 2 mm")
  std::string slug;  ///< folder and file names ("fixed-2mm"): [a-z0-9-] only
  ReconstructionParams params;
};

/// The paper's three configurations from the adaptive one: the fixed grid at its finest voxel
/// size (1 level), the fixed grid at its coarsest (voxel size x 2^(levels-1), 1 level), and
/// `adaptive` itself. The fixed finest grid gets 4x the block pool and hash tables, so that it
/// does not run out of room where the hierarchy does not. Throws `Error(InvalidArgument)` when
/// `adaptive` has a single level.
std::vector<ExperimentConfig> hierarchy_configs(const ReconstructionParams& adaptive);

/// Whether the tracked runs (for ATE and the whole loop's speed) are made.
enum class TrackedRuns {
  Auto,  ///< when the dataset has ground-truth poses and the same-pose runs use them
  Always,
  Never,
};

struct ExperimentParams {
  /// The first is the reference of the sdf-error and of the block saving (the fixed finest grid).
  std::vector<ExperimentConfig> configs;
  /// Poses of the same-pose runs. With ICP the first configuration tracks the camera and the
  /// others take its trajectory, so that every map sees the frames from the same poses.
  PoseSpec poses;
  TrackedRuns tracked = TrackedRuns::Auto;
  std::size_t first_frame = 0;
  std::size_t max_frames = 0;            ///< 0 = all
  std::filesystem::path reference_mesh;  ///< ground-truth mesh (PLY, OBJ, OFF); empty: none
  SdfErrorParams sdf;
  MeshEvalParams mesh_eval;
  MeshParams mesh;
  BadFramePolicy on_bad_frame = BadFramePolicy::Stop;
  std::filesystem::path out_dir;  ///< required
  /// An `out_dir` that holds files is refused unless this is set (then its old content goes).
  bool overwrite = false;
  /// Points of the sdf-error written to sdf_points.csv (for the heat map), at most.
  int64_t csv_points = 200'000;

  /// Throws `Error(InvalidArgument)` naming the bad setting.
  void validate() const;
};

struct ConfigResult {
  ExperimentConfig config;
  RunSummary run;                     ///< the same-pose run
  std::optional<RunSummary> tracked;  ///< the tracked run, when made
  StageTimes times, tracked_times;
  int64_t blocks = 0, peak_blocks = 0;  ///< at the end, at most during the run
  std::vector<int64_t> blocks_per_level;
  double memory_mib = 0;       ///< voxel and hash memory of the map at the end
  int64_t dropped_blocks = 0;  ///< blocks not allocated for lack of room
  double block_saving = 0;     ///< 1 - blocks / the first configuration's blocks
  MapSdfError sdf;             ///< at the points on the first configuration's mesh
  /// sdf.mean_abs_sdf_m over the coarsest fixed grid's (ExperimentResult::coarsest_fixed); 0
  /// without one.
  double sdf_ratio = 0;
  std::optional<MeshEvalResult> mesh_eval;  ///< against the reference mesh
};

struct ExperimentResult {
  std::string dataset;
  std::size_t frames = 0;  ///< frames each same-pose run went through
  std::string poses;       ///< the same-pose runs' pose source, as given
  int64_t sdf_samples = 0;
  /// Frames (with ground-truth poses) that decided which part of the reference mesh was observed:
  /// completeness counts that part only; 0 = the whole reference.
  std::size_t reference_observed_views = 0;
  std::vector<ConfigResult> configs;
  /// The coarsest single-level configuration, the reference of `ConfigResult::sdf_ratio` (paper
  /// Table I: the adaptive map's error beside the coarse grid's); -1 when there is none.
  int coarsest_fixed = -1;
  bool stopped = false;  ///< ended early by `stop_requested`; what finished is reported
  double wall_s = 0;
  std::vector<std::filesystem::path> files;
};

struct ExperimentCallbacks {
  /// A step begins ("fixed 2 mm: same poses", "adaptive: tracked (ICP)"): step `index` of
  /// `count`.
  std::function<void(std::string_view step, int index, int count)> on_step;
  /// Passed to each run (progress per frame, stop).
  RunCallbacks run;
};

/// Runs the experiment on `reader`'s frames and writes its files (report.json, report.md and the
/// rest; see the file comment). Throws `Error` for bad settings, a pose source the dataset cannot
/// serve, an `out_dir` holding files (without `overwrite`), and files it cannot read or write.
ExperimentResult run_experiment(DatasetReader& reader, const ExperimentParams& params,
                                const ExperimentCallbacks& callbacks = {});

/// The figures of a report (made by the plotting script, scripts/plot_experiment.py, from
/// report.json, blocks.csv, sdf_points.csv and the renders), relative to `out_dir`.
inline constexpr const char* kExperimentFigures[] = {
    "figures/blocks.png", "figures/renders.png", "figures/sdf_error.png", "figures/tradeoff.png"};

/// The report as Markdown (what report.md holds); it shows the figures of `kExperimentFigures`
/// that exist in `params.out_dir`.
std::string experiment_markdown(const ExperimentResult& result, const ExperimentParams& params);
/// The report as JSON (what report.json holds).
std::string experiment_json(const ExperimentResult& result, const ExperimentParams& params);

}  // namespace hivox

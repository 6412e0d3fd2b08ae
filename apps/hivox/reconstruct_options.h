#pragma once
// The settings of a reconstruction as the `reconstruct` and `demo` commands take them, shared with
// `experiment` (which runs several configurations) and `eval sdf-error`.

#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "dataset_options.h"
#include "hivox/mesh/params.h"
#include "hivox/pipeline/reconstruction.h"
#include "hivox/run/runner.h"
#include "hivox/view/live_view.h"

namespace hivox::cli {

struct ReconstructOptions {
  DatasetOptions data;
  std::string refine_criterion = "detail";
  std::string sensor_noise = "dataset";
  // Unset: the criterion's own defaults (detail: RefineParams{}, det-cov: the paper's 1e-4).
  std::optional<float> split_threshold, merge_threshold;
  std::string depth_sampling{to_string(FusionParams{}.depth_sampling)};
  std::string icp_loss = "huber";
  std::string poses = "icp";
  std::string device = "cpu";
  std::string on_bad_frame = "stop";
  std::string out;
  bool overwrite = false;
  ReconstructionParams params;
  MeshParams mesh;
  std::size_t frames = 0;
  std::size_t first_frame = 0;
  std::string map_in, map_out;
  std::string config_file;  ///< read before parsing (config_file.h); kept for --help
  std::string config_json;  ///< the effective settings, written as config.json
  /// The options that shape a map: with --map, those not given take the file's values.
  CLI::Option *levels_option = nullptr, *voxel_size_option = nullptr, *truncation_option = nullptr,
              *max_weight_option = nullptr, *no_color_option = nullptr;
  /// --view: serve the live page (the option's value: where); --view-fps, --view-linger.
  CLI::Option* view_option = nullptr;
  std::string view;
  double view_fps = LiveViewParams{}.render_hz;
  double view_linger_s = 0;
  int threads = 0;
  int render_every = 0;
  int read_ahead = RunParams{}.read_ahead_frames;
  int read_threads = RunParams{}.read_threads;
  bool no_color = false;
  bool quiet = false;
};

/// The output folder a run of `dataset` gets without --out: out/<dataset name>.
std::string default_out_dir(const std::string& dataset);

/// The run's parameters from the options (validated; errors name the option).
RunParams run_params(ReconstructOptions options);

/// The options that shape the reconstruction: poses, map, fusion, refinement, tracking, mesh,
/// threads, device.
void add_fusion_options(CLI::App* cmd, ReconstructOptions& o);
/// --quiet, --view, --view-fps, --view-linger and --config (a run's own session).
void add_session_options(CLI::App* cmd, ReconstructOptions& o);
/// Every option of `hivox reconstruct` (dataset, fusion, session, frames, maps, output).
void add_reconstruct_options(CLI::App* cmd, ReconstructOptions& o);

/// Interrupts (SIGINT, SIGTERM) set `stop_signal()` instead of ending the process, so that a run
/// stops at the next frame and writes what it has (a second interrupt ends it at once); the
/// previous handlers come back when the object goes.
class StopOnSignals {
 public:
  StopOnSignals();
  ~StopOnSignals();
  StopOnSignals(const StopOnSignals&) = delete;
  StopOnSignals& operator=(const StopOnSignals&) = delete;

 private:
  using Handler = void (*)(int);
  Handler previous_int_, previous_term_;
};

/// The signal that asked to stop, or 0.
int stop_signal();
/// The exit status of a run that an interrupt stopped: 128 + the signal (SIGINT when none was
/// recorded).
int interrupted_exit_status();

}  // namespace hivox::cli

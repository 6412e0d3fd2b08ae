// `hivox reconstruct DATASET`: the whole reconstruction of a sequence (the library's
// run_reconstruction), writing a mesh, the trajectory, statistics and renders; this file parses
// the flags and prints. `hivox demo` runs it on a built-in synthetic scene.

#include <unistd.h>

#include <csignal>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "commands.h"
#include "config_file.h"
#include "dataset_options.h"
#include "hivox/core/error.h"
#include "hivox/core/log.h"
#include "hivox/core/threads.h"
#include "hivox/core/timer.h"
#include "hivox/io/map_file.h"
#include "hivox/run/devices.h"
#include "hivox/run/runner.h"
#include "hivox/view/live_view.h"
#include "reconstruct_options.h"

namespace hivox::cli {

namespace fs = std::filesystem;

std::string default_out_dir(const std::string& dataset) {
  std::string name = fs::path(dataset).filename().string();
  if (name.empty()) name = fs::path(dataset).parent_path().filename().string();
  std::replace(name.begin(), name.end(), ':', '_');
  return (fs::path("out") / (name.empty() ? "run" : name)).string();
}

/// The run's settings from the command line (what the flags do not set directly).
RunParams run_params(ReconstructOptions options) {
  RefineParams& r = options.params.refine;
  r.criterion = parse_refine_criterion(options.refine_criterion);
  if (r.criterion == RefineCriterion::DetCov) {
    r.split_threshold = RefineParams::paper().split_threshold;
    r.merge_threshold = RefineParams::paper().merge_threshold;
  }
  r.split_threshold = options.split_threshold.value_or(r.split_threshold);
  r.merge_threshold = options.merge_threshold.value_or(r.merge_threshold);
  if (options.sensor_noise != "dataset")  // else the refinement takes the dataset's model
    r.noise = options.sensor_noise == "none" ? SensorNoise::none() : SensorNoise::kinect();
  options.params.device = Device::parse(options.device);
  options.params.fusion.depth_sampling = parse_depth_sampling(options.depth_sampling);
  options.params.track.loss = parse_robust_loss(options.icp_loss);
  if (options.no_color) {
    options.params.map.store_color = false;
    options.params.fusion.integrate_color = false;
  }
  if (!options.map_in.empty()) {
    // The map's own shape for every option left out; one given must agree (the run checks).
    const MapFileInfo info = read_map_file_info(options.map_in);
    MapParams& m = options.params.map;
    auto given = [](const CLI::Option* o) { return o != nullptr && o->count() > 0; };
    if (!given(options.levels_option)) m.levels = info.map.levels;
    if (!given(options.voxel_size_option)) m.voxel_size_m = info.map.voxel_size_m;
    if (!given(options.truncation_option)) m.truncation_m = info.map.truncation_m;
    if (!given(options.max_weight_option))
      options.params.fusion.max_weight = info.fusion.max_weight;
    if (!given(options.no_color_option)) {
      m.store_color = info.map.store_color;
      options.params.fusion.integrate_color = info.map.store_color;
    }
  }
  RunParams run;
  run.reconstruction = options.params;
  run.poses = PoseSpec::parse(options.poses);
  run.first_frame = options.first_frame;
  run.max_frames = options.frames;
  run.map_in = options.map_in;
  run.map_out = options.map_out;
  run.config_json = options.config_json;
  if (options.render_every < 0)
    fail(ErrorCode::InvalidArgument, "--render-every must be >= 0, got {}", options.render_every);
  run.render_every = options.render_every;
  run.mesh = options.mesh;
  run.out_dir = options.out.empty() ? default_out_dir(options.data.dataset) : options.out;
  run.overwrite = options.overwrite;
  run.on_bad_frame = parse_bad_frame_policy(options.on_bad_frame);
  run.read_ahead_frames = options.read_ahead;
  run.read_threads = options.read_threads;
  run.validate();
  return run;
}

namespace {

/// The signal that asked the run to stop (SIGINT, SIGTERM), or 0. Set by the handler, read
/// between frames.
volatile std::sig_atomic_t g_stop_signal = 0;

extern "C" void request_stop(int signal) {
  g_stop_signal = signal;
  std::signal(signal, SIG_DFL);  // a second interrupt ends the process at once
}

}  // namespace

StopOnSignals::StopOnSignals()
    : previous_int_(std::signal(SIGINT, request_stop)),
      previous_term_(std::signal(SIGTERM, request_stop)) {}

StopOnSignals::~StopOnSignals() {
  std::signal(SIGINT, previous_int_);
  std::signal(SIGTERM, previous_term_);
}

int stop_signal() {
  return g_stop_signal;
}

int interrupted_exit_status() {
  return 128 + (g_stop_signal != 0 ? static_cast<int>(g_stop_signal) : SIGINT);
}

namespace {

/// Centimetres, or millimetres below one (a synthetic or short run's error would read 0.00 cm).
std::string length(double m) {
  return m < 0.01 ? fmt::format("{:.2f} mm", 1000.0 * m) : fmt::format("{:.2f} cm", 100.0 * m);
}

void print_summary(const RunResult& result, const RunParams& run) {
  const Reconstruction& rec = *result.reconstruction;
  const RunSummary& s = result.summary;
  const auto frames = static_cast<double>(rec.frame_stats().size());
  fmt::print(
      "fused {} frames ({} lost, {} skipped without a pose, {} unreadable): {:.1f} fps "
      "processing, {:.1f} fps with reading\n",
      s.frames_fused, s.frames_lost, s.frames_skipped, s.frames_bad, frames / s.processing_s,
      frames / s.wall_s);
  const VoxelBlockMap& map = rec.map();
  fmt::print("blocks: {} (peak {}), per level {}, dropped {}, memory {:.1f} MiB\n",
             map.blocks_in_use(), rec.peak_blocks(), fmt::join(map.blocks_per_level(), "/"),
             map.dropped_blocks(), static_cast<double>(map.memory_bytes()) / (1 << 20));
  if (run.poses.source == PoseSource::Icp) {
    const TrackingCounts& tc = rec.tracking_counts();
    fmt::print("tracking: {} good, {} poor, {} lost (not fused)\n", tc.good, tc.poor, tc.lost);
  }
  if (s.ate)
    fmt::print(
        "trajectory error (ATE, {} poses aligned to the ground truth): RMSE {}, mean {}, max "
        "{}\n",
        s.ate->matched, length(s.ate->rmse_m), length(s.ate->mean_m), length(s.ate->max_m));
  fmt::print("mesh: {} vertices, {} triangles in {:.2f} s -> {}\n", s.mesh_vertices,
             s.mesh_triangles, s.mesh_s, (run.out_dir / "mesh.ply").string());
  fmt::print(
      "wrote {}/{{trajectory.txt, stats.json, "
      "{{,overview_}}{{depth,normals,shaded,color,levels}}.png}}\n",
      run.out_dir.string());
  if (!run.map_in.empty())
    fmt::print("continued the map {} (loaded in {:.2f} s)\n", run.map_in.string(), s.map_load_s);
  if (!run.map_out.empty())
    fmt::print("map saved to {} in {:.2f} s\n", run.map_out.string(), s.map_save_s);
}

/// Tells the live page how the run ended, keeps serving it for --view-linger seconds (an
/// interrupt ends that early) and reports what the view cost the frame loop.
void finish_live_view(LiveView& live, const RunResult& result, const RunParams& run,
                      const ReconstructOptions& options) {
  const RunSummary& s = result.summary;
  const LiveState state = s.end == RunEnd::Completed  ? LiveState::Finished
                          : s.end == RunEnd::BadFrame ? LiveState::Failed
                                                      : LiveState::Stopped;
  live.finish(*result.reconstruction, state,
              run.out_dir.empty() ? std::string()
                                  : fmt::format("results in {} (hivox view {})",
                                                run.out_dir.string(), run.out_dir.string()));
  if (!options.quiet)
    fmt::print("live view: {} renders, {:.2f} s of the frame loop ({:.1f}% of its processing)\n",
               live.renders(), live.frame_loop_ms() / 1e3,
               s.processing_s > 0 ? 100.0 * live.frame_loop_ms() / 1e3 / s.processing_s : 0.0);
  if (options.view_linger_s > 0 && s.end != RunEnd::StopRequested) {
    fmt::print("live view: the page stays at {} for {:g} s (Ctrl-C ends it)\n", live.url(),
               options.view_linger_s);
    std::fflush(stdout);
    const StopOnSignals stop_on_signals;
    Stopwatch linger;
    while (g_stop_signal == 0 && linger.elapsed_ms() < options.view_linger_s * 1e3) usleep(50'000);
    g_stop_signal = 0;
  }
}

void run_reconstruct(const ReconstructOptions& options) {
  if (options.threads > 0) set_thread_count(options.threads);
  const RunParams run = run_params(options);
  const std::unique_ptr<DatasetReader> reader = open_dataset(options.data);
  const DatasetInfo& info = reader->info();
  const bool tty = isatty(fileno(stdout)) != 0;
  std::unique_ptr<LiveView> live;
  if (options.view_option != nullptr && options.view_option->count() > 0) {
    LiveViewParams lp;
    lp.server = ViewServerParams::parse(options.view);
    lp.render_hz = options.view_fps;
    live = std::make_unique<LiveView>(lp);
    // Printed even with --quiet: the address is what --view asked for.
    fmt::print("live view: {}{}\n", live->url(),
               lp.server.loopback()
                   ? ""
                   : "  (listening beyond this machine: --view " + options.view + ")");
    std::fflush(stdout);
  }
  Stopwatch wall;
  std::size_t total = 0;
  RunCallbacks callbacks;
  callbacks.on_start = [&](const Reconstruction& rec, std::size_t frames) {
    total = frames;
    if (live) live->start(info.source, rec, frames);
    if (options.quiet) return;
    fmt::print("hivox reconstruct {}\n", info.source);
    const ReadPlan reading = read_plan(run, *reader);
    fmt::print("frames: {} of {}{} ({}x{}), poses: {}, threads: {}{}\n", frames, reader->size(),
               run.first_frame > 0 ? fmt::format(" from frame {}", run.first_frame) : "",
               info.rig.depth_camera.width, info.rig.depth_camera.height, run.poses.to_string(),
               reading.loop_threads,
               reading.frames > 0
                   ? fmt::format(", reading {} frames ahead on {} thread{}", reading.frames,
                                 reading.threads, reading.threads > 1 ? "s" : "")
                   : "");
    fmt::print("camera: {} [{}]\n", info.rig.depth_camera.to_string(), info.intrinsics_source);
    if (!info.distortion.none())
      fmt::print("lens distortion: {} ({})\n", info.distortion.to_string(),
                 info.undistorted ? "removed from every frame" : "kept: --keep-distortion");
    fmt::print("{}\n", rec.describe());
    if (!rec.params().device.is_cpu())
      if (const std::optional<DeviceInfo> gpu = describe_device(rec.params().device))
        fmt::print("gpu: {}\n", gpu->to_string());
    fmt::print("output: {}\n", run.out_dir.string());
  };
  // The progress line.
  callbacks.on_frame = [&](std::size_t i, const FrameStats& s, const Reconstruction& rec,
                           const RgbdFrame& frame) {
    if (live) live->frame(i, s, rec, frame);
    const std::size_t done = i + 1 - run.first_frame;
    if (options.quiet || !(tty || done % 50 == 0 || done == total)) return;
    const double fps = static_cast<double>(rec.frame_stats().size()) / (wall.elapsed_ms() / 1e3);
    fmt::print("{}frame {}/{}  {:.1f} fps  blocks {} ({})  dropped {}{}{}", tty ? "\r" : "", done,
               total, fps, s.blocks_total, fmt::join(s.blocks_per_level, "/"), rec.dropped_blocks(),
               run.poses.source == PoseSource::Icp
                   ? fmt::format("  lost {}", rec.tracking_counts().lost)
                   : std::string(),
               tty ? "   " : "\n");
    std::fflush(stdout);
  };
  callbacks.stop_requested = [] { return g_stop_signal != 0; };
  RunResult result;
  {
    const StopOnSignals stop_on_signals;
    result = run_reconstruction(*reader, run, callbacks);
  }
  const RunSummary& s = result.summary;
  if (!options.quiet) {
    if (tty) fmt::print("\n");
    print_summary(result, run);
  }
  if (live) finish_live_view(*live, result, run, options);
  // How the run ended decides the exit status (README, "Exit status").
  const std::size_t processed = result.reconstruction->frame_stats().size();
  switch (s.end) {
    case RunEnd::StopRequested:
      log::error(
          "{}: stopped by {} after {} of {} frames; the results of the frames so far are in {}",
          info.source, g_stop_signal == SIGTERM ? "SIGTERM" : "an interrupt (SIGINT)", processed,
          s.frames_total, run.out_dir.string());
      throw ExitStatus{interrupted_exit_status()};
    case RunEnd::BadFrame:
      log::error(
          "{}; the run stopped there (--on-bad-frame stop) and the results of the {} "
          "frames before it are in {}",
          s.end_reason, processed, run.out_dir.string());
      throw ExitStatus{kExitBadFrame};
    case RunEnd::Completed:
      break;
  }
  if (s.unusable) {
    log::error("{}: the result is of no use (see the warnings above); files written to {}",
               info.source, run.out_dir.string());
    throw ExitStatus{kExitUnusable};
  }
}

}  // namespace

void add_fusion_options(CLI::App* cmd, ReconstructOptions& o) {
  auto& p = o.params;
  cmd->add_option("--poses", o.poses,
                  "where camera poses come from: 'icp' (tracking against the model), 'gt' (the "
                  "dataset's ground truth) or a TUM trajectory file (camera-to-world)")
      ->capture_default_str();
  o.levels_option = cmd->add_option("--levels", p.map.levels, "resolution levels (1 = fixed grid)")
                        ->capture_default_str();
  o.voxel_size_option =
      cmd->add_option("--voxel-size", p.map.voxel_size_m, "finest voxel size, metres")
          ->capture_default_str();
  o.truncation_option =
      cmd->add_option("--truncation", p.map.truncation_m, "truncation band mu, metres")
          ->capture_default_str();
  cmd->add_option("--min-depth", p.fusion.depth_range.min_m,
                  "ignore depth nearer than this, metres")
      ->capture_default_str();
  cmd->add_option("--max-depth", p.fusion.depth_range.max_m,
                  "ignore depth farther than this, metres")
      ->capture_default_str();
  o.max_weight_option =
      cmd->add_option("--max-weight", p.fusion.max_weight, "cap of the per-voxel observation count")
          ->capture_default_str();
  cmd->add_option("--depth-sampling", o.depth_sampling,
                  "how voxels read the depth image: 'bilinear' (no pixel staircase on slanted "
                  "surfaces) or 'nearest' pixel (integration ~1.2x faster)")
      ->capture_default_str();
  cmd->add_option("--max-blocks", p.map.max_blocks,
                  "voxel-block pool size (all levels); memory is used as blocks are allocated")
      ->capture_default_str();
  cmd->add_option("--hash-buckets", p.map.buckets_per_level, "hash buckets per level (power of 2)")
      ->capture_default_str();
  cmd->add_option("--hash-excess", p.map.excess_per_level, "hash overflow entries per level")
      ->capture_default_str();
  cmd->add_option("--refine", o.refine_criterion,
                  "complexity criterion that moves blocks between levels: 'detail' (how far the "
                  "TSDF departs from linear near the surface, metres; noise-aware) or 'det-cov' "
                  "(the paper's determinant of the normal covariance)")
      ->capture_default_str();
  cmd->add_option("--split-threshold", o.split_threshold,
                  fmt::format("split a block whose complexity exceeds this (default: {:g} m for "
                              "detail, {:g} for det-cov)",
                              p.refine.split_threshold, RefineParams::paper().split_threshold));
  cmd->add_option("--merge-threshold", o.merge_threshold,
                  fmt::format("merge 8 siblings whose complexity is below this, < the split "
                              "threshold (default: {:g} m for detail, {:g} for det-cov)",
                              p.refine.merge_threshold, RefineParams::paper().merge_threshold));
  cmd->add_option("--refine-every", p.refine.every_n_frames, "split/merge after every N-th frame")
      ->capture_default_str();
  cmd->add_option("--refine-min-weight", p.refine.min_weight,
                  "voxels observed fewer times do not count in the criterion")
      ->capture_default_str();
  cmd->add_option("--refine-min-updates", p.refine.min_updates,
                  "frames a block must have been fused since it changed before it is judged")
      ->capture_default_str();
  cmd->add_option("--refine-settled-weight", p.refine.settled_weight,
                  "observations after which a block's fused noise counts as settled; young blocks "
                  "split only on detail well above their noise (lower: more blocks stay fine)")
      ->capture_default_str();
  cmd->add_option("--refine-unmeshable-cells", p.refine.split_unmeshable_cells,
                  "also split a block with this many cells whose surface its level cannot mesh "
                  "(corners behind a surface seen at a grazing angle never observed), and keep "
                  "such merges from happening; 0: off")
      ->capture_default_str();
  cmd->add_option("--refine-split-weight-scale", p.refine.split_weight_scale,
                  "a split block's children start with the parent's interpolated weight times "
                  "this, (0, 1]: lower lets new fine observations outweigh the coarse values "
                  "sooner")
      ->capture_default_str();
  cmd->add_option("--sensor-noise", o.sensor_noise,
                  "depth noise model the refinement compares detail with: 'dataset' (the "
                  "dataset's own: Kinect-class for recorded sets, none for noise-free synthetic "
                  "depth), 'kinect' or 'none'")
      ->check(CLI::IsMember({"dataset", "kinect", "none"}))
      ->capture_default_str();
  cmd->add_option("--refine-noise-factor", p.refine.split_noise_factor,
                  fmt::format("split when detail exceeds this times the sensor noise at the "
                              "block's depth (merge below {:g} times as much)",
                              p.refine.merge_noise_ratio))
      ->capture_default_str();
  cmd->add_option("--icp-loss", o.icp_loss,
                  "robust weighting of ICP residuals: none, huber or tukey")
      ->capture_default_str();
  cmd->add_option("--icp-iterations", p.track.iterations,
                  "ICP iterations per pyramid level, finest first (the count sets the levels)")
      ->capture_default_str()
      ->delimiter(',');
  cmd->add_option("--icp-model-subsample", p.track.model_subsample,
                  "raycast the model for tracking at 1/N of the frame resolution (1, 2 or 4)")
      ->capture_default_str();
  cmd->add_flag("!--no-motion-prior", p.track.constant_velocity,
                "start ICP at the previous pose instead of extrapolating the last motion");
  o.no_color_option = cmd->add_flag("--no-color", o.no_color,
                                    "do not store or fuse colour (4 instead of 8 B/voxel)");
  cmd->add_flag("!--no-raycast", p.raycast_every_frame,
                "skip the per-frame raycast (renders are still made at the end)");
  cmd->add_flag("--refine-after-raycast", p.refine_after_raycast,
                "refine the hierarchy after each frame's model raycast, not before (on a device "
                "the refinement then overlaps the raycast; the next frame tracks against the map "
                "before the splits and merges; with --device cuda it has faulted on a GPU: "
                "docs/cuda.md)");
  cmd->add_option("--on-bad-frame", o.on_bad_frame,
                  "a frame that cannot be read (missing or corrupt file): 'stop' the run there "
                  "(the frames before it are written, exit status 4) or 'skip' it with a "
                  "warning (counted in stats.json)")
      ->check(CLI::IsMember({"stop", "skip"}))
      ->capture_default_str();
  cmd->add_option("--read-ahead", o.read_ahead,
                  "frames read ahead while one is processed (0 = each when its turn comes; -1 = "
                  "two per reading thread)")
      ->check(CLI::Range(-1, 64))
      ->capture_default_str();
  cmd->add_option("--read-threads", o.read_threads,
                  "threads that read ahead (0 = the cores the loop leaves free, at most 8: none "
                  "for a CPU run on all cores, all but one with --device cuda)")
      ->check(CLI::Range(0, 64))
      ->capture_default_str();
  cmd->add_option("--render-every", o.render_every,
                  "also write the renders of every N-th frame (0 = only at the end)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--mesh-min-weight", o.mesh.min_weight,
                  "voxels observed fewer times do not make surface")
      ->capture_default_str();
  cmd->add_option("--threads", o.threads, "CPU threads (0 = all cores)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--device", o.device,
                  "where the frames run: cpu, or cuda / cuda:N (builds with the CUDA loop; "
                  "docs/cuda.md)")
      ->capture_default_str();
}

void add_session_options(CLI::App* cmd, ReconstructOptions& o) {
  cmd->add_flag("--quiet", o.quiet, "print nothing but warnings and errors");
  o.view_option =
      cmd->add_option("--view", o.view,
                      "watch the run in a browser: serves a live page (the model's raycast, the "
                      "depth frame, trajectory, blocks and stage times, tracking) at "
                      "http://127.0.0.1:PORT/, printed at the start. Optional value: PORT, ADDRESS "
                      "or ADDRESS:PORT (default 127.0.0.1 and a free port; 0.0.0.0 serves other "
                      "machines too)")
          ->expected(0, 1)
          ->type_name("[ADDR:PORT]");
  cmd->add_option("--view-fps", o.view_fps,
                  "renders of the model per second for --view at most (each a raycast at 320 px "
                  "wide on the run's thread)")
      ->check(CLI::Range(0.0, 120.0))
      ->capture_default_str();
  cmd->add_option("--view-linger", o.view_linger_s,
                  "keep serving the --view page this many seconds after the run ends")
      ->check(CLI::Range(0.0, 86400.0))
      ->capture_default_str();
  cmd->add_option("--config", o.config_file,
                  "read settings from a config.json that a run wrote into its output folder; "
                  "options given here override it (repeats a run: hivox reconstruct DATASET "
                  "--config OUT/config.json --out NEW)")
      ->type_name("FILE");
}

namespace {

struct DemoOptions {
  ReconstructOptions run;
  std::string scene = "desk";
  std::size_t frames = 150;
  std::string noise = "kinect";
};

}  // namespace

void add_demo_command(CLI::App& app) {
  auto options = std::make_shared<DemoOptions>();
  options->run.out = "out/demo";
  options->run.overwrite = true;  // the demo's folder is its own: each run replaces it whole
  CLI::App* cmd = app.add_subcommand(
      "demo",
      "Reconstruct a built-in synthetic scene (no download): renders an office desk with a "
      "Kinect-like noise model along a camera path and runs `hivox reconstruct` on it, tracking "
      "the camera by ICP from the first pose and reporting the trajectory error. Writes mesh.ply, "
      "renders, trajectory.txt and stats.json to --out.");
  cmd->add_option("--scene", options->scene,
                  "built-in scene (room, desk, box, spheres, keyboard, blob)")
      ->capture_default_str();
  cmd->add_option("--frames", options->frames, "frames along the scene's camera path")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--noise", options->noise, "depth noise model: kinect or none")
      ->capture_default_str();
  cmd->add_option("--out", options->run.out, "output folder")->capture_default_str();
  add_fusion_options(cmd, options->run);
  add_session_options(cmd, options->run);
  cmd->footer(
      "Examples:\n"
      "  hivox demo\n"
      "  hivox demo --scene keyboard --noise none --voxel-size 0.002 --truncation 0.008\n"
      "The same scenes can be used anywhere a dataset is expected, e.g.\n"
      "  hivox reconstruct 'synthetic:desk?frames=300&noise=kinect'\n"
      "or written to disk as a TUM sequence with `hivox synth`.");
  cmd->callback([options, cmd] {
    ReconstructOptions run = options->run;
    run.config_json = effective_config_json(*cmd);
    run.data.dataset = fmt::format("synthetic:{}?frames={}&noise={}", options->scene,
                                   options->frames, options->noise);
    run_reconstruct(run);
  });
}

void add_reconstruct_options(CLI::App* cmd, ReconstructOptions& o) {
  ReconstructOptions* options = &o;
  add_dataset_options(cmd, options->data);
  add_fusion_options(cmd, *options);
  add_session_options(cmd, *options);
  cmd->add_option("--frames", options->frames, "process N frames (0 = all)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--first-frame", options->first_frame,
                  "start at this frame of the dataset (0 = its first)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--save-map", options->map_out,
                  "save the map to this file (.hvx) at the end, also when the run is "
                  "interrupted; `hivox mesh`, `render`, `info`, `export` and --map read it")
      ->type_name("FILE");
  cmd->add_option("--map", options->map_in,
                  "continue the map saved in this file: the frames are fused into it (its voxel "
                  "size, levels, truncation, colour and maximum weight apply; tracking starts "
                  "from the map's last pose)")
      ->type_name("FILE");
  cmd->add_option("--out", options->out,
                  "output folder (default out/<dataset name>); written whole when the run ends")
      ->type_name("DIR");
  cmd->add_flag("--overwrite", options->overwrite,
                "replace an output folder that holds files already (without it such a folder is "
                "refused, so that two runs' files never mix)");
  cmd->footer(dataset_help() +
              "Examples:\n"
              "  hivox reconstruct ../shared/data/tum_fr1_rpy --levels 1 --voxel-size 0.005 "
              "--truncation 0.02\n"
              "  hivox reconstruct ~/data/fr2_desk --preset tum_fr2 --poses my_trajectory.txt\n"
              "  hivox reconstruct ../shared/data/tum_fr1_rpy --frames 300 --save-map rpy.hvx\n"
              "  hivox reconstruct ../shared/data/tum_fr1_rpy --first-frame 300 --map rpy.hvx "
              "--save-map rpy_all.hvx\n");
}

void add_reconstruct_command(CLI::App& app) {
  auto options = std::make_shared<ReconstructOptions>();
  CLI::App* cmd = app.add_subcommand(
      "reconstruct",
      "Fuse an RGB-D sequence into a TSDF map and write the mesh (mesh.ply), the trajectory "
      "(trajectory.txt, TUM format), statistics (stats.json) and renders of the model (PNG).");
  add_reconstruct_options(cmd, *options);
  cmd->callback([options, cmd] {
    options->config_json = effective_config_json(*cmd);
    run_reconstruct(*options);
  });
}

}  // namespace hivox::cli

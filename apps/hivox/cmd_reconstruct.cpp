// `hivox reconstruct DATASET`: the whole reconstruction of a sequence, writing a mesh, the
// trajectory, statistics and renders. `hivox demo` runs it on a built-in synthetic scene.

#include <unistd.h>

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
#include "dataset_options.h"
#include "hivox/core/error.h"
#include "hivox/core/log.h"
#include "hivox/core/threads.h"
#include "hivox/core/timer.h"
#include "hivox/eval/trajectory_eval.h"
#include "hivox/io/image_io.h"
#include "hivox/io/ply.h"
#include "hivox/io/stats_json.h"
#include "hivox/io/trajectory_io.h"
#include "hivox/mesh/extract_mesh.h"
#include "hivox/pipeline/reconstruction.h"
#include "hivox/raycast/render.h"

namespace hivox::cli {

namespace {

namespace fs = std::filesystem;

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
  std::string out;
  ReconstructionParams params;
  MeshParams mesh;
  std::size_t frames = 0;
  int threads = 0;
  int render_every = 0;
  bool no_color = false;
  bool quiet = false;
};

/// Poses from a TUM trajectory file, matched to frames by nearest timestamp (20 ms).
class PoseFile {
 public:
  explicit PoseFile(const fs::path& path) : path_(path), poses_(read_tum_trajectory(path)) {
    if (poses_.empty()) fail(ErrorCode::InvalidData, "{}: no poses in the file", path.string());
    std::stable_sort(poses_.begin(), poses_.end(), [](const StampedPose& a, const StampedPose& b) {
      return a.timestamp_s < b.timestamp_s;
    });
  }
  std::optional<Pose> at(double t_s) const {
    const long i = find_nearest_pose(poses_, t_s, 0.02);
    return i < 0 ? std::nullopt : std::optional<Pose>(poses_[static_cast<std::size_t>(i)].T_wc);
  }

 private:
  fs::path path_;
  std::vector<StampedPose> poses_;
};

void write_renders(const RaycastResult& r, const fs::path& dir, const std::string& prefix) {
  write_png(dir / (prefix + "depth.png"), render_depth(r.depth_m));
  write_png(dir / (prefix + "normals.png"), render_normals(r));
  write_png(dir / (prefix + "shaded.png"), render_shaded(r));
  write_png(dir / (prefix + "color.png"), render_colors(r));
  write_png(dir / (prefix + "levels.png"), render_levels(r));
}

std::string default_out_dir(const std::string& dataset) {
  std::string name = fs::path(dataset).filename().string();
  if (name.empty()) name = fs::path(dataset).parent_path().filename().string();
  std::replace(name.begin(), name.end(), ':', '_');
  return (fs::path("out") / (name.empty() ? "run" : name)).string();
}

void run_reconstruct(ReconstructOptions options) {
  if (options.threads > 0) set_thread_count(options.threads);
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
  options.params.validate();
  options.mesh.validate();
  if (options.render_every < 0)
    fail(ErrorCode::InvalidArgument, "--render-every must be >= 0, got {}", options.render_every);

  const std::unique_ptr<DatasetReader> reader = open_dataset(options.data);
  const DatasetInfo& info = reader->info();
  for (const std::string& w : info.warnings) log::warn("{}", w);
  const bool tracking = options.poses == "icp";
  std::unique_ptr<PoseFile> pose_file;
  if (tracking) {
    if (!options.params.raycast_every_frame)
      fail(ErrorCode::InvalidArgument,
           "--no-raycast: tracking (--poses icp) needs the per-frame raycast of the model");
  } else if (options.poses != "gt")
    pose_file = std::make_unique<PoseFile>(options.poses);
  else if (!info.has_ground_truth)
    fail(ErrorCode::InvalidArgument,
         "{}: --poses gt, but the dataset has no ground-truth poses; pass --poses FILE (a TUM "
         "trajectory)",
         info.source);

  const fs::path out = options.out.empty() ? default_out_dir(options.data.dataset) : options.out;
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec)
    fail(ErrorCode::Io, "{}: cannot create output directory ({})", out.string(), ec.message());

  const std::size_t total =
      options.frames > 0 ? std::min(options.frames, reader->size()) : reader->size();
  Reconstruction rec(options.params, info.rig);
  const std::string params_text = rec.describe();  // with the dataset's noise model
  if (!options.quiet) {
    fmt::print("hivox reconstruct {}\n", info.source);
    fmt::print("frames: {} of {} ({}x{}), poses: {}, threads: {}\n", total, reader->size(),
               info.rig.depth_camera.width, info.rig.depth_camera.height, options.poses,
               thread_count());
    fmt::print("camera: {} [{}]\n", info.rig.depth_camera.to_string(), info.intrinsics_source);
    if (!info.distortion.none())
      fmt::print("lens distortion: {} ({})\n", info.distortion.to_string(),
                 info.undistorted ? "removed from every frame" : "kept: --keep-distortion");
    fmt::print("{}\noutput: {}\n", params_text, out.string());
  }

  const bool tty = isatty(fileno(stdout)) != 0;
  Stopwatch wall;
  // Per-frame renders and the progress line.
  auto progress = [&](std::size_t i, const FrameStats& s, const Pose& T_wc) {
    if (options.render_every > 0 && (i + 1) % static_cast<std::size_t>(options.render_every) == 0)
      write_renders(rec.render(info.rig.depth_camera, T_wc), out, fmt::format("frame{:06d}_", i));
    if (!options.quiet && (tty || (i + 1) % 50 == 0 || i + 1 == total)) {
      const double fps = static_cast<double>(rec.frame_stats().size()) / (wall.elapsed_ms() / 1e3);
      fmt::print("{}frame {}/{}  {:.1f} fps  blocks {} ({})  dropped {}{}{}", tty ? "\r" : "",
                 i + 1, total, fps, s.blocks_total, fmt::join(s.blocks_per_level, "/"),
                 rec.map().dropped_blocks(),
                 tracking ? fmt::format("  lost {}", rec.tracking_counts().lost) : std::string(),
                 tty ? "   " : "\n");
      std::fflush(stdout);
    }
  };
  std::size_t skipped = 0;
  std::vector<StampedPose> ground_truth;
  for (std::size_t i = 0; i < total; ++i) {
    Stopwatch read_watch;
    RgbdFrame frame = reader->read(i);
    const double read_ms = read_watch.elapsed_ms();
    if (frame.T_wc_gt) ground_truth.push_back({frame.timestamp_s, *frame.T_wc_gt});
    if (tracking) {
      // The first frame fixes the world frame: at its true pose when known (so that renders and
      // meshes line up with the ground truth), else at the origin.
      const FrameStats& s =
          rec.track_and_integrate(frame, read_ms, frame.T_wc_gt.value_or(Pose::Identity()));
      if (s.tracking == TrackingQuality::Lost)
        log::warn(
            "frame {} (t = {:.6f} s): tracking lost (inliers {:.0f} %, residual {:.1f} mm); "
            "not fused, previous pose kept",
            i, frame.timestamp_s, 100.0 * s.track_inlier_ratio, 1000.0 * s.track_rms_m);
      progress(i, s, rec.trajectory().back().T_wc);
      continue;
    }
    const std::optional<Pose> T_wc = pose_file ? pose_file->at(frame.timestamp_s) : frame.T_wc_gt;
    if (!T_wc) {
      ++skipped;
      log::warn_once("reconstruct.no_pose",
                     "frame {} (t = {:.6f} s) has no pose within 20 ms: skipped (counted in "
                     "stats.json as skipped_frames)",
                     i, frame.timestamp_s);
      continue;
    }
    progress(i, rec.integrate(frame, *T_wc, read_ms), *T_wc);
  }
  const double wall_s = wall.elapsed_ms() / 1e3;
  if (!options.quiet && tty) fmt::print("\n");
  if (rec.frame_stats().empty())
    fail(ErrorCode::InvalidData, "{}: no frame could be integrated", info.source);

  // Results.
  write_tum_trajectory(out / "trajectory.txt", rec.trajectory(),
                       fmt::format("hivox reconstruct {} (poses: {})", info.source, options.poses));
  const Pose last_pose = rec.trajectory().back().T_wc;
  write_renders(rec.render(info.rig.depth_camera, last_pose), out, "");
  // The whole model from above and behind the trajectory, with its refinement levels.
  const PinholeCamera overview_camera{600.0f, 600.0f, 479.5f, 359.5f, 960, 720};
  float overview_depth = 0.0f;
  const Pose overview = rec.overview_pose(overview_camera, &overview_depth);
  write_renders(rec.render(overview_camera, overview, overview_depth), out, "overview_");
  Stopwatch mesh_watch;
  const TriangleMesh mesh = extract_mesh(rec.map(), options.mesh);
  write_ply(out / "mesh.ply", mesh);
  const double mesh_s = mesh_watch.elapsed_ms() / 1e3;
  RunInfo run;
  run.dataset = info.source;
  run.pose_source = options.poses;
  run.wall_s = wall_s;
  run.threads = thread_count();
  run.parameters = params_text;
  run.skipped_frames = static_cast<int64_t>(skipped);
  std::optional<AteResult> ate;
  if (ground_truth.size() >= 3 && options.poses != "gt") {
    ate = evaluate_ate(ground_truth, rec.trajectory());
    run.ate_rmse_m = ate->rmse_m;
  }
  write_stats_json(out / "stats.json", rec, run);

  if (!options.quiet) {
    const auto& frames = rec.frame_stats();
    double total_ms = 0;
    for (const FrameStats& f : frames) total_ms += f.total_ms;
    fmt::print(
        "integrated {} frames ({} skipped without a pose): {:.1f} fps processing, {:.1f} fps "
        "with reading\n",
        frames.size(), skipped, 1000.0 * static_cast<double>(frames.size()) / total_ms,
        static_cast<double>(frames.size()) / wall_s);
    fmt::print("blocks: {} (peak {}), per level {}, dropped {}, memory {:.1f} MiB\n",
               rec.map().blocks_in_use(), rec.peak_blocks(),
               fmt::join(rec.map().blocks_per_level(), "/"), rec.map().dropped_blocks(),
               static_cast<double>(rec.map().memory_bytes()) / (1 << 20));
    if (tracking) {
      const TrackingCounts& tc = rec.tracking_counts();
      fmt::print("tracking: {} good, {} poor, {} lost (not fused)\n", tc.good, tc.poor, tc.lost);
    }
    if (ate) {
      // Centimetres, or millimetres below one (a synthetic or short run's error would read
      // "0.00 cm").
      auto length = [](double m) {
        return m < 0.01 ? fmt::format("{:.2f} mm", 1000.0 * m)
                        : fmt::format("{:.2f} cm", 100.0 * m);
      };
      fmt::print(
          "trajectory error (ATE, {} poses aligned to the ground truth): RMSE {}, mean {}, max "
          "{}\n",
          ate->matched, length(ate->rmse_m), length(ate->mean_m), length(ate->max_m));
    }
    fmt::print("mesh: {} vertices, {} triangles in {:.2f} s -> {}\n", mesh.vertex_count(),
               mesh.triangle_count(), mesh_s, (out / "mesh.ply").string());
    fmt::print(
        "wrote {}/{{trajectory.txt, stats.json, "
        "{{,overview_}}{{depth,normals,shaded,color,levels}}.png}}\n",
        out.string());
  }
}

void add_fusion_options(CLI::App* cmd, ReconstructOptions& o) {
  auto& p = o.params;
  cmd->add_option("--poses", o.poses,
                  "where camera poses come from: 'icp' (tracking against the model), 'gt' (the "
                  "dataset's ground truth) or a TUM trajectory file (camera-to-world)")
      ->capture_default_str();
  cmd->add_option("--levels", p.map.levels, "resolution levels (1 = fixed grid)")
      ->capture_default_str();
  cmd->add_option("--voxel-size", p.map.voxel_size_m, "finest voxel size, metres")
      ->capture_default_str();
  cmd->add_option("--truncation", p.map.truncation_m, "truncation band mu, metres")
      ->capture_default_str();
  cmd->add_option("--min-depth", p.fusion.depth_range.min_m,
                  "ignore depth nearer than this, metres")
      ->capture_default_str();
  cmd->add_option("--max-depth", p.fusion.depth_range.max_m,
                  "ignore depth farther than this, metres")
      ->capture_default_str();
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
  cmd->add_flag("--no-color", o.no_color, "do not store or fuse colour (4 instead of 8 B/voxel)");
  cmd->add_flag("!--no-raycast", p.raycast_every_frame,
                "skip the per-frame raycast (renders are still made at the end)");
  cmd->add_option("--render-every", o.render_every,
                  "also write the renders of every N-th frame (0 = only at the end)")
      ->capture_default_str();
  cmd->add_option("--mesh-min-weight", o.mesh.min_weight,
                  "voxels observed fewer times do not make surface")
      ->capture_default_str();
  cmd->add_option("--threads", o.threads, "CPU threads (0 = all cores)")->capture_default_str();
  cmd->add_option("--device", o.device,
                  "where the map lives and the stages run: cpu, or cuda[:N] (needs a build with "
                  "the CUDA backend)")
      ->capture_default_str();
  cmd->add_flag("--quiet", o.quiet, "print nothing but warnings and errors");
}

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
      ->capture_default_str();
  cmd->add_option("--noise", options->noise, "depth noise model: kinect or none")
      ->capture_default_str();
  cmd->add_option("--out", options->run.out, "output folder")->capture_default_str();
  add_fusion_options(cmd, options->run);
  cmd->footer(
      "Examples:\n"
      "  hivox demo\n"
      "  hivox demo --scene keyboard --noise none --voxel-size 0.002 --truncation 0.008\n"
      "The same scenes can be used anywhere a dataset is expected, e.g.\n"
      "  hivox reconstruct 'synthetic:desk?frames=300&noise=kinect'\n"
      "or written to disk as a TUM sequence with `hivox synth`.");
  cmd->callback([options] {
    ReconstructOptions run = options->run;
    run.data.dataset = fmt::format("synthetic:{}?frames={}&noise={}", options->scene,
                                   options->frames, options->noise);
    run_reconstruct(run);
  });
}

void add_reconstruct_command(CLI::App& app) {
  auto options = std::make_shared<ReconstructOptions>();
  CLI::App* cmd = app.add_subcommand(
      "reconstruct",
      "Fuse an RGB-D sequence into a TSDF map and write the mesh (mesh.ply), the trajectory "
      "(trajectory.txt, TUM format), statistics (stats.json) and renders of the model (PNG).");
  add_dataset_options(cmd, options->data);
  add_fusion_options(cmd, *options);
  cmd->add_option("--frames", options->frames, "process the first N frames (0 = all)")
      ->capture_default_str();
  cmd->add_option("--out", options->out, "output folder (default out/<dataset name>)")
      ->type_name("DIR");
  cmd->footer(dataset_help() +
              "Examples:\n"
              "  hivox reconstruct ../shared/data/tum_fr1_rpy --levels 1 --voxel-size 0.005 "
              "--truncation 0.02\n"
              "  hivox reconstruct ~/data/fr2_desk --preset tum_fr2 --poses my_trajectory.txt\n");
  cmd->callback([options] { run_reconstruct(*options); });
}

}  // namespace hivox::cli

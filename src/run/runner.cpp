#include "hivox/run/runner.h"

#include <algorithm>
#include <system_error>
#include <thread>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "hivox/core/error.h"
#include "hivox/core/log.h"
#include "hivox/core/threads.h"
#include "hivox/core/timer.h"
#if defined(HIVOX_WITH_CUDA)
#include "hivox/cuda/gpu_reconstruction.h"
#endif
#include "hivox/io/atomic_file.h"
#include "hivox/io/map_file.h"
#include "hivox/io/ply.h"
#include "hivox/io/read_ahead.h"
#include "hivox/io/trajectory_io.h"
#include "hivox/mesh/extract_mesh.h"
#include "hivox/output/output_folder.h"
#include "hivox/output/renders.h"
#include "hivox/output/stats_json.h"
#include "hivox/run/devices.h"

namespace hivox {

namespace fs = std::filesystem;

PoseSpec PoseSpec::parse(std::string_view text) {
  if (text == "icp") return {PoseSource::Icp, {}};
  if (text == "gt") return {PoseSource::GroundTruth, {}};
  if (text.empty())
    fail(ErrorCode::InvalidArgument,
         "poses must be 'icp', 'gt' or a TUM trajectory file, got an empty name");
  return {PoseSource::File, fs::path(text)};
}

std::string PoseSpec::to_string() const {
  switch (source) {
    case PoseSource::Icp:
      return "icp";
    case PoseSource::GroundTruth:
      return "gt";
    case PoseSource::File:
      return file.string();
  }
  return "?";
}

std::string_view to_string(BadFramePolicy policy) {
  return policy == BadFramePolicy::Skip ? "skip" : "stop";
}

BadFramePolicy parse_bad_frame_policy(std::string_view name) {
  if (name == "stop") return BadFramePolicy::Stop;
  if (name == "skip") return BadFramePolicy::Skip;
  fail(ErrorCode::InvalidArgument, "on_bad_frame must be 'stop' or 'skip', got '{}'", name);
}

namespace {
/// The frames a run of `params` goes through on `reader` (none when the first is beyond it).
std::size_t frames_to_run(const RunParams& params, const DatasetReader& reader) {
  const std::size_t available = reader.size() - std::min(params.first_frame, reader.size());
  return params.max_frames > 0 ? std::min(params.max_frames, available) : available;
}
}  // namespace

std::unique_ptr<Reconstruction> make_reconstruction(const ReconstructionParams& params,
                                                    const CameraRig& rig,
                                                    std::unique_ptr<VoxelBlockMap> map,
                                                    const MapSession& session) {
  check_device(params.device);
#if defined(HIVOX_WITH_CUDA)
  if (!params.device.is_cpu())
    return cuda::make_reconstruction(params, rig, std::move(map), session);
#endif
  if (map == nullptr) return std::make_unique<Reconstruction>(params, rig);
  return std::make_unique<Reconstruction>(params, rig, std::move(map), session);
}

void RunParams::validate() const {
  reconstruction.validate();
  check_device(reconstruction.device);
  mesh.validate();
  if (render_every < 0)
    fail(ErrorCode::InvalidArgument, "render_every must be >= 0, got {}", render_every);
  if (read_ahead_frames < -1 || read_ahead_frames > 64)
    fail(ErrorCode::InvalidArgument, "read_ahead_frames must be -1 (auto) or in [0, 64], got {}",
         read_ahead_frames);
  if (read_threads < 0 || read_threads > 64)
    fail(ErrorCode::InvalidArgument, "read_threads must be in [0, 64] (0: auto), got {}",
         read_threads);
  if (poses.source == PoseSource::Icp && !reconstruction.raycast_every_frame)
    fail(ErrorCode::InvalidArgument,
         "tracking (poses icp) needs the per-frame raycast of the model (raycast_every_frame)");
  if (!map_in.empty() && map_in == map_out)
    fail(ErrorCode::InvalidArgument,
         "the map to continue and the map to save are the same file ({}): save to another name",
         map_in.string());
  if (poses.source == PoseSource::File && poses.file.empty())
    fail(ErrorCode::InvalidArgument, "poses from a file, but no file is named");
}

ReadPlan read_plan(const RunParams& params, const DatasetReader& reader) {
  int threads = params.read_threads;
  if (threads == 0) {
    // The cores the loop leaves free: all but the thread driving a GPU, those beyond the CPU
    // loop's threads.
    const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    const int busy = params.reconstruction.device.is_cpu() ? thread_count() : 1;
    threads = std::clamp(cores - busy, 0, 8);
  }
  if (!reader.reads_concurrently()) threads = std::min(threads, 1);
  const int frames =
      params.read_ahead_frames < 0 ? ReadAhead::frames_for(threads) : params.read_ahead_frames;
  if (frames == 0) return {0, 0, thread_count()};
  threads = std::max(threads, 1);
  return {frames, threads,
          ReadAhead::sharing(reader.reads_concurrently(), frames_to_run(params, reader), frames,
                             threads, thread_count())
              .caller_threads};
}

namespace {

/// Poses from a TUM trajectory file, matched to frames by nearest timestamp (20 ms).
class PoseFile {
 public:
  explicit PoseFile(const fs::path& path) : poses_(read_tum_trajectory(path)) {
    if (poses_.empty()) fail(ErrorCode::InvalidData, "{}: no poses in the file", path.string());
    const std::string order = timestamp_order_problems(poses_);
    if (!order.empty())
      log::warn("{}: {}; frames are matched to the nearest pose in time", path.string(), order);
    std::stable_sort(poses_.begin(), poses_.end(), [](const StampedPose& a, const StampedPose& b) {
      return a.timestamp_s < b.timestamp_s;
    });
  }
  std::optional<Pose> at(double t_s) const {
    const long i = find_nearest_pose(poses_, t_s, 0.02);
    return i < 0 ? std::nullopt : std::optional<Pose>(poses_[static_cast<std::size_t>(i)].T_wc);
  }

 private:
  std::vector<StampedPose> poses_;
};

/// The frame loop's state: the reconstruction, where poses come from, what happened so far.
class Run {
 public:
  Run(DatasetReader& reader, const RunParams& params, const RunCallbacks& callbacks)
      : reader_(reader), info_(reader.info()), params_(params), callbacks_(callbacks) {}

  RunResult go() {
    check_pose_source();
    // The dataset's doubts (a depth scale that looks wrong, frames far apart in time), logged
    // when it was opened, belong to the run's result too: stats.json lists them with its own.
    summary_.warnings = info_.warnings;
    OutputFolder folder(params_.out_dir, params_.overwrite);
    folder_ = &folder;
    RunResult result;
    if (params_.first_frame >= reader_.size())
      fail(ErrorCode::InvalidArgument, "{}: first frame {}, but the dataset has {} frames",
           info_.source, params_.first_frame, reader_.size());
    result.reconstruction = make_reconstruction();
    rec_ = result.reconstruction.get();
    if (params_.poses.source == PoseSource::Icp) rec_->check_tracking();
    summary_.frames_total = frames_to_run(params_, reader_);
    if (callbacks_.on_start) callbacks_.on_start(*rec_, summary_.frames_total);
    frame_loop();
    if (rec_->frame_stats().empty()) {
      if (summary_.end == RunEnd::BadFrame)
        throw Error(ErrorCode::InvalidData, summary_.end_reason);
      fail(ErrorCode::InvalidData, "{}: no frame could be integrated", info_.source);
    }
    finish();
    folder.commit();
    for (fs::path& f : summary_.files) f = folder.final_path(f);
    result.summary = std::move(summary_);
    return result;
  }

 private:
  /// A new reconstruction, or one that continues the map file `map_in`.
  std::unique_ptr<Reconstruction> make_reconstruction() {
    if (params_.map_in.empty())
      return hivox::make_reconstruction(params_.reconstruction, info_.rig);
    Stopwatch load;
    const ReconstructionParams& p = params_.reconstruction;
    LoadedMap loaded = read_map_file(params_.map_in, p.map);
    check_map_continues(loaded.info, params_.map_in, p.map, p.fusion);
    session_start_ = loaded.info.session.last_pose;
    auto rec = hivox::make_reconstruction(p, info_.rig, std::move(loaded.map), loaded.info.session);
    summary_.map_load_s = load.elapsed_ms() / 1e3;
    return rec;
  }

  void check_pose_source() {
    switch (params_.poses.source) {
      case PoseSource::Icp:
        break;
      case PoseSource::GroundTruth:
        if (!info_.has_ground_truth)
          fail(ErrorCode::InvalidArgument,
               "{}: --poses gt, but the dataset has no ground-truth poses; pass --poses FILE (a "
               "TUM trajectory)",
               info_.source);
        break;
      case PoseSource::File:
        pose_file_ = std::make_unique<PoseFile>(params_.poses.file);
        break;
    }
  }

  void frame_loop() {
    Stopwatch wall;
    double processing_ms = 0.0;
    const std::size_t end = params_.first_frame + summary_.frames_total;
    const ReadPlan plan = read_plan(params_, reader_);
    ReadAhead frames(reader_, params_.first_frame, end, plan.frames, plan.threads);
    for (std::size_t i = params_.first_frame; i < end; ++i) {
      if (callbacks_.stop_requested && callbacks_.stop_requested()) {
        summary_.end = RunEnd::StopRequested;
        break;
      }
      Stopwatch read_watch;
      RgbdFrame frame;
      try {
        frame = frames.next();
      } catch (const Error& e) {
        if (params_.on_bad_frame == BadFramePolicy::Stop) {
          summary_.end = RunEnd::BadFrame;
          summary_.end_reason = e.what();
          break;
        }
        ++summary_.frames_bad;
        log::warn("frame {}: {}; skipped (--on-bad-frame skip)", i, e.what());
        continue;
      }
      const double read_ms = read_watch.elapsed_ms();
      check_frame(i, frame);
      if (frame.T_wc_gt) ground_truth_.push_back({frame.timestamp_s, *frame.T_wc_gt});
      const FrameStats* s = process(i, frame, read_ms);
      if (s == nullptr) continue;
      processing_ms += s->total_ms;
      if (s->fused && s->valid_pixels == 0) ++summary_.frames_no_depth;
      if (params_.render_every > 0 &&
          (i + 1) % static_cast<std::size_t>(params_.render_every) == 0 && folder_->writes())
        write(write_renders(rec_->render(info_.rig.depth_camera, rec_->trajectory().back().T_wc),
                            rec_->params().map, folder_->dir(), fmt::format("frame{:06d}_", i)));
      if (callbacks_.on_frame) callbacks_.on_frame(i, *s, *rec_, frame);
    }
    summary_.wall_s = wall.elapsed_ms() / 1e3;
    summary_.processing_s = processing_ms / 1e3;
  }

  /// What a frame says about the input: timestamps in order, depths inside the range.
  void check_frame(std::size_t i, const RgbdFrame& frame) {
    if (last_timestamp_ && !(frame.timestamp_s > *last_timestamp_)) ++timestamps_out_of_order_;
    last_timestamp_ = frame.timestamp_s;
    if (i > params_.first_frame || frame.depth_m.empty()) return;
    // The first frame's depths against the range: most beyond it means a wrong depth scale or
    // too short a range (each frame's pixels inside it are counted by fusion).
    const DepthRange& range = params_.reconstruction.fusion.depth_range;
    int64_t measured = 0, beyond = 0, nearer = 0;
    std::vector<float> depths;
    for (std::size_t k = 0; k < frame.depth_m.size(); ++k) {
      const float d = frame.depth_m.data()[k];
      if (!(d > 0.0f)) continue;
      ++measured;
      beyond += d > range.max_m;
      nearer += d < range.min_m;
      if (k % 16 == 0) depths.push_back(d);
    }
    if (measured == 0 || (beyond + nearer) * 2 < measured) return;
    std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
    warn(fmt::format(
        "frame {}: {:.0f} % of the measured depths lie outside the depth range {} (median {:.2f} "
        "m): check the depth scale (--depth-scale, now {}) or the range (--min-depth, "
        "--max-depth)",
        i, 100.0 * static_cast<double>(beyond + nearer) / static_cast<double>(measured),
        range.to_string(), depths.empty() ? 0.0f : depths[depths.size() / 2],
        info_.rig.depth_scale > 0 ? fmt::format("{:g} per metre", info_.rig.depth_scale)
                                  : std::string("metric")));
  }

  /// Tracks and fuses, or fuses at the given pose; null for a frame skipped without a pose.
  const FrameStats* process(std::size_t i, const RgbdFrame& frame, double read_ms) {
    if (params_.poses.source == PoseSource::Icp) {
      // The first frame fixes the world frame: at its true pose when known, else at the origin.
      // Continuing a map, tracking starts at the map's last pose (where the scan stopped), else
      // there.
      const Pose start =
          session_start_ ? *session_start_ : frame.T_wc_gt.value_or(Pose::Identity());
      const FrameStats& s = rec_->track_and_integrate(frame, read_ms, start);
      if (s.tracking == TrackingQuality::Lost) {
        ++summary_.frames_lost;
        log::warn(
            "frame {} (t = {:.6f} s): tracking lost (inliers {:.0f} %, residual {:.1f} mm); not "
            "fused, previous pose kept",
            i, frame.timestamp_s, 100.0 * s.track_inlier_ratio, 1000.0 * s.track_rms_m);
      } else {
        ++summary_.frames_fused;
      }
      return &s;
    }
    const std::optional<Pose> T_wc = pose_file_ ? pose_file_->at(frame.timestamp_s) : frame.T_wc_gt;
    if (!T_wc) {
      ++summary_.frames_skipped;
      log::warn_once("reconstruct.no_pose",
                     "frame {} (t = {:.6f} s) has no pose within 20 ms: skipped (counted in "
                     "stats.json as skipped_frames)",
                     i, frame.timestamp_s);
      return nullptr;
    }
    ++summary_.frames_fused;
    return &rec_->integrate(frame, *T_wc, read_ms);
  }

  /// The results: the trajectory, the renders from the last pose and from above, the mesh and
  /// the statistics (into the output folder, when there is one), the trajectory's error, and
  /// what makes the result doubtful.
  void finish() {
    const bool files = folder_->writes();
    const fs::path& out = folder_->dir();
    if (!params_.map_out.empty()) {  // first: the map is what a rerun cannot recover cheaply
      Stopwatch save;
      write_map_file(params_.map_out, rec_->map(), params_.reconstruction.fusion, rec_->session());
      summary_.map_save_s = save.elapsed_ms() / 1e3;
      summary_.files.push_back(params_.map_out);
    }
    if (ground_truth_.size() >= 3 && params_.poses.source != PoseSource::GroundTruth)
      summary_.ate = evaluate_ate(ground_truth_, rec_->trajectory());
    if (files) {
      write_tum_trajectory(
          out / "trajectory.txt", rec_->trajectory(),
          fmt::format("hivox reconstruct {} (poses: {})", info_.source, params_.poses.to_string()));
      summary_.files.push_back(out / "trajectory.txt");
      const Pose last_pose = rec_->trajectory().back().T_wc;
      write(
          write_renders(rec_->render(info_.rig.depth_camera, last_pose), rec_->params().map, out));
      // The whole model from above and behind the trajectory, with its refinement levels.
      const PinholeCamera overview_camera{600.0f, 600.0f, 479.5f, 359.5f, 960, 720};
      float overview_depth = 0.0f;
      const Pose overview = rec_->overview_pose(overview_camera, &overview_depth);
      write(write_renders(rec_->render(overview_camera, overview, overview_depth),
                          rec_->params().map, out, "overview_"));
    }
    Stopwatch mesh_watch;
    const TriangleMesh mesh = rec_->extract_mesh(params_.mesh);
    summary_.mesh_vertices = mesh.vertex_count();
    summary_.mesh_triangles = mesh.triangle_count();
    if (files) {
      write_ply(out / "mesh.ply", mesh);
      summary_.files.push_back(out / "mesh.ply");
    }
    summary_.mesh_s = mesh_watch.elapsed_ms() / 1e3;
    judge();
    if (files) {
      RunInfo run;
      run.dataset = info_.source;
      run.pose_source = params_.poses.to_string();
      run.wall_s = summary_.wall_s;
      run.threads = thread_count();
      if (!rec_->params().device.is_cpu()) run.gpu = describe_device(rec_->params().device);
      run.parameters = rec_->describe();
      run.skipped_frames = static_cast<int64_t>(summary_.frames_skipped);
      run.bad_frames = static_cast<int64_t>(summary_.frames_bad);
      run.frames_fused = static_cast<int64_t>(summary_.frames_fused);
      run.end = summary_.end == RunEnd::Completed       ? "completed"
                : summary_.end == RunEnd::StopRequested ? "stopped"
                                                        : "bad frame";
      run.warnings = summary_.warnings;
      run.unusable = summary_.unusable;
      if (summary_.ate) run.ate_rmse_m = summary_.ate->rmse_m;
      run.depth_scale = info_.rig.depth_scale;
      run.config_json = params_.config_json;
      if (!params_.config_json.empty()) {
        write_file_atomically(out / "config.json", params_.config_json);
        summary_.files.push_back(out / "config.json");
      }
      write_stats_json(out / "stats.json", *rec_, run);
      summary_.files.push_back(out / "stats.json");
    }
  }

  /// The checks on the whole run: what makes its result doubtful, or of no use.
  void judge() {
    const std::size_t processed = rec_->frame_stats().size();
    if (timestamps_out_of_order_ > 0)
      warn(
          fmt::format("{} frame(s) have a timestamp not after the one before (duplicated or out "
                      "of order): they were fused in file order",
                      timestamps_out_of_order_));
    if (summary_.frames_no_depth > 0)
      warn(fmt::format("{} of {} frames had no depth inside the depth range {}",
                       summary_.frames_no_depth, processed,
                       params_.reconstruction.fusion.depth_range.to_string()));
    if (summary_.frames_no_depth > 0 && summary_.frames_no_depth == summary_.frames_fused)
      summary_.unusable = true;
    if (summary_.frames_lost * 2 > processed) {
      warn(fmt::format("tracking was lost on {} of {} frames", summary_.frames_lost, processed));
      summary_.unusable = true;
    }
    if (summary_.mesh_triangles == 0) {
      warn("the mesh is empty: no surface was observed often enough to be meshed");
      summary_.unusable = true;
    }
    if (summary_.frames_bad > 0)
      warn(fmt::format("{} frame(s) could not be read and were skipped", summary_.frames_bad));
    warn_poor_stretches();
  }

  /// Poor frames are fused, so a stretch of them can move the model, and with it every pose
  /// after, while the run counts no frame lost. A stretch of kPoorStretchFrames or more is
  /// warned about (fr1/rpy tracks all 694 frames good; every 3rd of its frames gives 7 poor in
  /// a row and 15 cm of ATE, every 4th 10 and 35 cm).
  void warn_poor_stretches() {
    constexpr int64_t kPoorStretchFrames = 5;
    constexpr std::size_t kStretchesNamed = 3;
    const TrackParams& track = rec_->params().track;
    const std::vector<PoorTrackingStretch> stretches =
        poor_tracking_stretches(rec_->frame_stats(), track, kPoorStretchFrames);
    for (std::size_t k = 0; k < stretches.size() && k < kStretchesNamed; ++k) {
      const PoorTrackingStretch& s = stretches[k];
      std::vector<std::string> causes;
      if (s.few_inliers > 0)
        causes.push_back(fmt::format(
            "inliers {:.0f}-{:.0f} %, under {:.0f} %: the camera moved far between frames, too "
            "fast or with frames missing",
            100.0 * s.min_inlier_ratio, 100.0 * s.max_inlier_ratio,
            100.0 * track.poor_inlier_ratio));
      if (s.unconstrained > 0)
        causes.push_back(
            "the geometry in view left a direction of motion unconstrained, as a plane or a "
            "smooth shape does");
      warn(fmt::format(
          "frames {} to {}: tracking was poor on {} frames in a row{} ({}), and they were fused: "
          "the model, and the poses tracked against it after them, may be offset",
          s.first_index, s.last_index, s.poor,
          s.lost > 0 ? fmt::format(" and lost on {}", s.lost) : std::string(),
          fmt::join(causes, "; ")));
    }
    if (stretches.size() > kStretchesNamed)
      warn(fmt::format("{} more stretches of {} or more poor frames in a row",
                       stretches.size() - kStretchesNamed, kPoorStretchFrames));
  }

  void warn(std::string line) {
    log::warn("{}", line);
    summary_.warnings.push_back(std::move(line));
  }

  void write(const std::vector<fs::path>& written) {
    summary_.files.insert(summary_.files.end(), written.begin(), written.end());
  }

  DatasetReader& reader_;
  const DatasetInfo& info_;
  const RunParams& params_;
  const RunCallbacks& callbacks_;
  OutputFolder* folder_ = nullptr;
  Reconstruction* rec_ = nullptr;
  std::unique_ptr<PoseFile> pose_file_;
  std::optional<Pose> session_start_;  ///< the continued map's last pose
  std::vector<StampedPose> ground_truth_;
  std::optional<double> last_timestamp_;
  std::size_t timestamps_out_of_order_ = 0;
  RunSummary summary_;
};

}  // namespace

RunResult run_reconstruction(DatasetReader& reader, const RunParams& params,
                             const RunCallbacks& callbacks) {
  params.validate();
  return Run(reader, params, callbacks).go();
}

}  // namespace hivox

#include "hivox/pipeline/reconstruction.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <optional>
#include <utility>

#include <fmt/format.h>

#include "hivox/core/error.h"
#include "hivox/core/timer.h"

namespace hivox {

void FrameStats::take_track(const TrackResult& t) {
  tracking = t.quality;
  track_inlier_ratio = t.inlier_ratio;
  track_rms_m = t.rms_m;
  track_condition = t.condition;
  track_iterations = t.iterations;
}

void ReconstructionParams::validate() const {
  map.validate();
  fusion.validate();
  refine.validate();
  raycast.validate();
  track.validate();
}

std::string ReconstructionParams::to_string(const CameraRig* rig) const {
  const std::optional<SensorNoise> sensor =
      rig != nullptr ? std::optional<SensorNoise>(rig->depth_noise) : std::nullopt;
  return fmt::format("device: {}\nmap: {}\nfusion: {}\n{}raycast: {}{}\ntrack: {}",
                     device.to_string(), map.to_string(), fusion.to_string(),
                     map.levels > 1 ? "refine: " + refine.to_string(sensor) +
                                          (refine_after_raycast ? ", after the raycast" : "") + "\n"
                                    : std::string(),
                     raycast.to_string(),
                     raycast_every_frame ? " (every frame)" : " (renders only)", track.to_string());
}

Reconstruction::Reconstruction(const ReconstructionParams& params, const CameraRig& rig)
    : Reconstruction(params, rig, nullptr, MapSession{}, false, nullptr) {}

Reconstruction::Reconstruction(const ReconstructionParams& params, const CameraRig& rig,
                               std::unique_ptr<VoxelBlockMap> map, const MapSession& session)
    : Reconstruction(params, rig, std::move(map), session, true, nullptr) {}

Reconstruction::Reconstruction(const ReconstructionParams& params, const CameraRig& rig,
                               std::unique_ptr<DeviceLoop> loop, std::unique_ptr<VoxelBlockMap> map,
                               const MapSession& session)
    : Reconstruction(params, rig, std::move(map), session, true, std::move(loop)) {}

Reconstruction::~Reconstruction() = default;

namespace {
/// The CPU stages' device: the CPU unless a device loop runs the frames (then the CPU's objects
/// only serve renders and checks on the host's copy).
Device host_stage_device(const ReconstructionParams& p, const DeviceLoop* loop) {
  if (loop != nullptr) return Device::cpu();
  p.device.require_available();
  return p.device;
}
}  // namespace

Reconstruction::Reconstruction(const ReconstructionParams& params, const CameraRig& rig,
                               std::unique_ptr<VoxelBlockMap> map, const MapSession& session,
                               bool continues_map, std::unique_ptr<DeviceLoop> loop)
    : params_(params),
      rig_(rig),
      integrator_(params_.fusion),
      refiner_(params_.refine, rig.depth_noise),
      raycaster_(params_.raycast),
      tracker_(params_.track, params_.fusion.depth_range, host_stage_device(params_, loop.get())),
      resumed_(session),
      continues_map_(continues_map && (map != nullptr || loop == nullptr)),
      loop_(std::move(loop)) {
  params_.validate();
  params_.map.warn_about_combinations();
  rig_.validate();
  if (!continues_map_) {
    map_ = std::make_unique<VoxelBlockMap>(params_.map, loop_ ? Device::cpu() : params_.device);
    return;
  }
  if (!map) fail(ErrorCode::InvalidArgument, "no map to continue");
  const std::string diff = params_.map.shape_difference(map->params());
  if (!diff.empty())
    fail(ErrorCode::InvalidArgument, "the map to continue differs from the settings: {}", diff);
  if (session.frames_fused < 0)
    fail(ErrorCode::InvalidArgument, "a map session of {} frames", session.frames_fused);
  map_ = std::move(map);
  params_.map = map_->params();  // its capacities are the map's own
  refiner_.resume_after(session.frames_fused);
}

const VoxelBlockMap& Reconstruction::map() const {
  if (loop_ && map_stale_) {
    loop_->download_map(*map_);
    map_stale_ = false;
  }
  return *map_;
}

VoxelBlockMap& Reconstruction::map() {
  std::as_const(*this).map();
  return *map_;
}

const RaycastResult& Reconstruction::last_raycast() const {
  if (!loop_) return raycaster_.result();
  if (model_stale_) {
    device_model_ = loop_->model();
    model_stale_ = false;
  }
  return device_model_;
}

TriangleMesh Reconstruction::extract_mesh(const MeshParams& params, RemovedPieces* removed) const {
  if (loop_) return loop_->extract_mesh(params, removed);
  return hivox::extract_mesh(*map_, params, removed);
}

int64_t Reconstruction::blocks_in_use() const {
  if (!loop_) return map_->blocks_in_use();
  const std::vector<int64_t> per_level = loop_->blocks_per_level();
  return std::accumulate(per_level.begin(), per_level.end(), int64_t{0});
}

std::vector<int64_t> Reconstruction::blocks_per_level() const {
  return loop_ ? loop_->blocks_per_level() : map_->blocks_per_level();
}

int64_t Reconstruction::dropped_blocks() const {
  return loop_ ? loop_->dropped_blocks() : map_->dropped_blocks();
}

int64_t Reconstruction::map_memory_bytes() const {
  return loop_ ? loop_->map_memory_bytes() : map_->memory_bytes();
}

MapSession Reconstruction::session() const {
  MapSession s = resumed_;
  s.frames_fused = resumed_.frames_fused +
                   static_cast<int64_t>(std::count_if(frames_.begin(), frames_.end(),
                                                      [](const FrameStats& f) { return f.fused; }));
  if (!trajectory_.empty()) s.last_pose = trajectory_.back().T_wc;
  s.camera = rig_.depth_camera;
  return s;
}

const FrameStats& Reconstruction::integrate(const RgbdFrame& frame, const Pose& T_wc,
                                            double read_ms) {
  FrameStats s;
  Stopwatch total;
  if (loop_) {
    s = loop_->integrate(frame, T_wc);
    map_stale_ = model_stale_ = true;
  } else {
    fuse(frame, T_wc, s);
  }
  s.read_ms = read_ms;
  return record(frame, T_wc, total, s);
}

const FrameStats& Reconstruction::track_and_integrate(const RgbdFrame& frame, double read_ms,
                                                      const Pose& T_wc_first) {
  if (loop_) {
    Stopwatch total;
    Pose T_wc;
    FrameStats s = loop_->track_and_integrate(frame, T_wc_first, &last_track_, &T_wc);
    s.read_ms = read_ms;
    map_stale_ = model_stale_ = true;
    return record(frame, T_wc, total, s);
  }
  if (trajectory_.empty() && !continues_map_) {
    last_track_ = TrackResult{};
    last_track_.T_wc = T_wc_first;
    last_track_.quality = TrackingQuality::Good;
    motion_.restart();
    return integrate(frame, T_wc_first, read_ms);
  }
  FrameStats s;
  s.read_ms = read_ms;
  Stopwatch total;
  // The pose tracking starts from: the last frame's, or where a continued map's run resumes.
  const Pose T_prev = trajectory_.empty() ? T_wc_first : trajectory_.back().T_wc;
  // Track against the model seen from the previous pose (raycast now if it was not).
  const RaycastResult& model = raycaster_.result();
  if (model.depth_m.empty() || !model.T_wc.isApprox(T_prev) ||
      model.camera.width != model_camera().width) {
    raycaster_.raycast(*map_, model_camera(), T_prev, params_.fusion.depth_range);
  }
  last_track_ =
      tracker_.track(frame.depth_m, rig_.depth_camera, raycaster_.result(), motion_.start(T_prev));
  s.track_ms = total.elapsed_ms();
  s.take_track(last_track_);
  const Pose T_wc = motion_.keep(T_prev, last_track_);
  if (last_track_.quality == TrackingQuality::Lost) {
    s.fused = false;
    s.valid_pixels = last_track_.valid_pixels;
    return record(frame, T_wc, total, s);
  }
  fuse(frame, T_wc, s);
  return record(frame, T_wc, total, s);
}

const FrameStats& Reconstruction::record(const RgbdFrame& frame, const Pose& T_wc,
                                         const Stopwatch& total, FrameStats& s) {
  s.index = frame.index;
  s.timestamp_s = frame.timestamp_s;
  // On a device, its counts: the host's copy of the map is refreshed only when read.
  s.blocks_per_level = blocks_per_level();
  s.blocks_total = blocks_in_use();
  peak_blocks_ = std::max(peak_blocks_, s.blocks_total);
  s.total_ms = total.elapsed_ms();
  switch (s.tracking) {
    case TrackingQuality::Good:
      ++tracking_counts_.good;
      break;
    case TrackingQuality::Poor:
      ++tracking_counts_.poor;
      break;
    case TrackingQuality::Lost:
      ++tracking_counts_.lost;
      break;
  }
  trajectory_.push_back({frame.timestamp_s, T_wc});
  frames_.push_back(std::move(s));
  return frames_.back();
}

void Reconstruction::fuse(const RgbdFrame& frame, const Pose& T_wc, FrameStats& s) {
  Stopwatch stage;

  const FusionInput in = fusion_input(rig_, frame, T_wc);
  const Allocation a = integrator_.allocate(*map_, in);
  s.allocate_ms = stage.lap_ms();
  integrator_.integrate(*map_, in, a.visible_blocks);
  s.integrate_ms = stage.lap_ms();
  s.valid_pixels = a.stats.valid_pixels;
  s.visible_blocks = static_cast<int64_t>(a.visible_blocks.size());
  s.new_blocks = a.stats.new_blocks;
  s.dropped_blocks = a.stats.dropped_blocks;

  const auto refine = [&] {
    if (map_->levels() < 2) return;
    stage.restart();
    const RefineStats r = refiner_.refine(*map_, a.visible_blocks, T_wc);
    s.refine_ms = stage.lap_ms();
    s.splits = r.splits;
    s.merges = r.merges;
    s.refine_waiting = r.waiting;
  };
  if (!params_.refine_after_raycast) refine();
  if (params_.raycast_every_frame) {
    stage.restart();
    RaycastStats rs;
    const RaycastHints hints = hints_.build(
        frame.depth_m, rig_.depth_camera, params_.track.model_subsample, T_wc,
        params_.previous_raycast_hints ? &raycaster_.result() : nullptr, params_.map.truncation_m);
    raycaster_.raycast(*map_, model_camera(), T_wc, params_.fusion.depth_range, hints, &rs);
    s.raycast_ms = stage.lap_ms();
    s.raycast_hits = rs.hits;
    s.raycast_hits_at_hint = rs.found_at_hint;
  }
  if (params_.refine_after_raycast) refine();
}

PinholeCamera Reconstruction::model_camera() const {
  return rig_.depth_camera.subsampled(params_.track.model_subsample);
}

Pose Reconstruction::overview_pose(const PinholeCamera& camera, float* max_depth_m) const {
  // Robust centre and extent of the model: the blocks' centres, trimmed of the farthest 5 %.
  std::vector<Eigen::Vector3d> centres;
  for (const BlockRef& b : loop_ ? loop_->allocated_blocks() : map_->allocated_blocks()) {
    const double s = params_.map.block_size_at(b.level);
    centres.emplace_back((b.pos.x + 0.5) * s, (b.pos.y + 0.5) * s, (b.pos.z + 0.5) * s);
  }
  Eigen::Vector3d forward = Eigen::Vector3d::UnitZ(), up = -Eigen::Vector3d::UnitY();
  if (!trajectory_.empty()) {
    forward.setZero();
    up.setZero();
    for (const StampedPose& p : trajectory_) {
      forward += p.T_wc.linear().col(2);
      up -= p.T_wc.linear().col(1);
    }
    forward.normalize();
    up.normalize();
  }
  Eigen::Vector3d target = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& c : centres) target += c;
  if (!centres.empty()) target /= static_cast<double>(centres.size());
  std::vector<double> dist;
  for (const Eigen::Vector3d& c : centres) dist.push_back((c - target).norm());
  double radius = 1.0;
  if (!dist.empty()) {
    std::nth_element(dist.begin(), dist.begin() + dist.size() * 95 / 100, dist.end());
    radius = std::max(0.1, dist[dist.size() * 95 / 100]);
  }
  const double half_fov = std::atan(
      0.5 * std::min(camera.width / std::abs(camera.fx), camera.height / std::abs(camera.fy)));
  const double d = 1.15 * radius / std::sin(half_fov);
  const Eigen::Vector3d eye = target - d * (forward - 0.6 * up).normalized();
  if (max_depth_m != nullptr) *max_depth_m = static_cast<float>(d + 2.0 * radius);
  return look_at(eye, target, up);
}

RaycastResult Reconstruction::render(const PinholeCamera& camera, const Pose& T_wc,
                                     float max_depth_m) const {
  DepthRange range = params_.fusion.depth_range;
  if (max_depth_m > 0.0f) range.max_m = max_depth_m;
  if (loop_) return loop_->render(camera, T_wc, range);
  // A raycaster of its own: the per-frame raycast stays as it is.
  Raycaster raycaster(params_.raycast);
  return raycaster.raycast(*map_, camera, T_wc, range);
}

std::vector<PoorTrackingStretch> poor_tracking_stretches(std::span<const FrameStats> frames,
                                                         const TrackParams& track,
                                                         int64_t min_poor) {
  std::vector<PoorTrackingStretch> found;
  std::optional<PoorTrackingStretch> open;
  const auto close = [&] {
    if (open && open->poor >= min_poor) found.push_back(*open);
    open.reset();
  };
  for (const FrameStats& f : frames) {
    if (f.tracking == TrackingQuality::Good) {
      close();
      continue;
    }
    if (!open) open = PoorTrackingStretch{.first_index = f.index};
    PoorTrackingStretch& s = *open;
    s.last_index = f.index;
    if (f.tracking == TrackingQuality::Lost) {
      ++s.lost;
      continue;
    }
    ++s.poor;
    if (f.track_inlier_ratio < track.poor_inlier_ratio) {
      ++s.few_inliers;
      s.min_inlier_ratio = std::min(s.min_inlier_ratio, f.track_inlier_ratio);
      s.max_inlier_ratio = std::max(s.max_inlier_ratio, f.track_inlier_ratio);
    } else {
      s.unconstrained += f.track_condition < track.poor_condition;
    }
  }
  close();
  return found;
}

StageTimes mean_stage_times(std::span<const FrameStats> frames) {
  StageTimes t;
  if (frames.empty()) return t;
  for (const FrameStats& f : frames) {
    t.read_ms += f.read_ms;
    t.upload_ms += f.upload_ms;
    t.track_ms += f.track_ms;
    t.allocate_ms += f.allocate_ms;
    t.integrate_ms += f.integrate_ms;
    t.refine_ms += f.refine_ms;
    t.raycast_ms += f.raycast_ms;
    t.total_ms += f.total_ms;
  }
  const double n = static_cast<double>(frames.size());
  for (double* v : {&t.read_ms, &t.upload_ms, &t.track_ms, &t.allocate_ms, &t.integrate_ms,
                    &t.refine_ms, &t.raycast_ms, &t.total_ms})
    *v /= n;
  return t;
}

}  // namespace hivox

#include "hivox/pipeline/reconstruction.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "hivox/core/error.h"
#include "hivox/core/timer.h"

namespace hivox {

namespace {

RaycastParams raycast_params_for(const ReconstructionParams& p) {
  RaycastParams r = p.raycast;
  r.truncation_m = p.fusion.truncation_m;
  r.min_depth_m = p.fusion.min_depth_m > 0.0f ? p.fusion.min_depth_m : r.min_depth_m;
  r.max_depth_m = p.fusion.max_depth_m;
  return r;
}

/// `p` with the refinement's noise model taken from the dataset where it asks for that.
ReconstructionParams with_dataset_noise(ReconstructionParams p, const DatasetInfo& info) {
  if (p.refine.noise_from_dataset) p.refine.noise = info.depth_noise;
  return p;
}

TrackParams track_params_for(const ReconstructionParams& p) {
  TrackParams t = p.track;
  t.min_depth_m = p.fusion.min_depth_m > 0.0f ? p.fusion.min_depth_m : t.min_depth_m;
  t.max_depth_m = p.fusion.max_depth_m;
  return t;
}

}  // namespace

void ReconstructionParams::validate() const {
  map.validate();
  fusion.validate();
  refine.validate();
  raycast_params_for(*this).validate();
  track_params_for(*this).validate();
}

std::string ReconstructionParams::to_string() const {
  return fmt::format("map: {}\nfusion: {}\n{}raycast: {}{}\ntrack: {}", map.to_string(),
                     fusion.to_string(),
                     map.levels > 1 ? "refine: " + refine.to_string() + "\n" : std::string(),
                     raycast_params_for(*this).to_string(),
                     raycast_every_frame ? " (every frame)" : " (renders only)", track.to_string());
}

Reconstruction::Reconstruction(const ReconstructionParams& params, const DatasetInfo& info)
    : params_(with_dataset_noise(params, info)),
      info_(info),
      integrator_(params_.fusion),
      refiner_(params_.refine),
      raycaster_(raycast_params_for(params_)),
      tracker_(track_params_for(params_)) {
  params_.validate();
  params_.fusion.check_against(params_.map);
  info_.depth_camera.validate("depth camera");
  map_ = std::make_unique<VoxelBlockMap>(params_.map);
}

const FrameStats& Reconstruction::integrate(const RgbdFrame& frame, const Pose& T_wc,
                                            double read_ms) {
  FrameStats s;
  s.read_ms = read_ms;
  Stopwatch total;
  fuse(frame, T_wc, s);
  return record(frame, T_wc, total, s);
}

const FrameStats& Reconstruction::track_and_integrate(const RgbdFrame& frame, double read_ms,
                                                      const Pose& T_wc_first) {
  if (trajectory_.empty()) {
    last_track_ = TrackResult{};
    last_track_.T_wc = T_wc_first;
    last_track_.quality = TrackingQuality::Good;
    motion_ = Pose::Identity();
    return integrate(frame, T_wc_first, read_ms);
  }
  FrameStats s;
  s.read_ms = read_ms;
  Stopwatch total;
  const Pose& T_prev = trajectory_.back().T_wc;
  // Track against the model seen from the previous pose (raycast now if it was not).
  const RaycastResult& model = raycaster_.result();
  if (model.depth_m.empty() || !model.T_wc.isApprox(T_prev) ||
      model.camera.width != model_camera().width) {
    raycaster_.raycast(*map_, model_camera(), T_prev);
  }
  const Pose T_init = params_.track.constant_velocity ? Pose(T_prev * motion_) : T_prev;
  last_track_ = tracker_.track(frame.depth_m, info_.depth_camera, raycaster_.result(), T_init);
  s.track_ms = total.elapsed_ms();
  s.tracking = last_track_.quality;
  s.track_inlier_ratio = last_track_.inlier_ratio;
  s.track_rms_m = last_track_.rms_m;
  s.track_condition = last_track_.condition;
  s.track_iterations = last_track_.iterations;
  if (last_track_.quality == TrackingQuality::Lost) {
    s.fused = false;
    s.valid_pixels = last_track_.valid_pixels;
    motion_ = Pose::Identity();
    return record(frame, T_prev, total, s);
  }
  const Pose T_wc = last_track_.T_wc;
  motion_ = T_prev.inverse() * T_wc;
  fuse(frame, T_wc, s);
  return record(frame, T_wc, total, s);
}

const FrameStats& Reconstruction::record(const RgbdFrame& frame, const Pose& T_wc,
                                         const Stopwatch& total, FrameStats& s) {
  s.index = frame.index;
  s.timestamp_s = frame.timestamp_s;
  s.blocks_total = map_->blocks_in_use();
  s.blocks_per_level = map_->blocks_per_level();
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

  const FusionInput in = fusion_input(info_, frame, T_wc);
  const AllocationStats a = integrator_.allocate(*map_, in);
  s.allocate_ms = stage.lap_ms();
  integrator_.integrate(*map_, in);
  s.integrate_ms = stage.lap_ms();
  s.valid_pixels = a.valid_pixels;
  s.visible_blocks = a.visible_blocks;
  s.new_blocks = a.new_blocks;
  s.dropped_blocks = a.dropped_blocks;

  if (map_->levels() > 1) {
    stage.restart();
    const RefineStats r =
        refiner_.refine(*map_, integrator_.visible_blocks(), params_.fusion.truncation_m, T_wc);
    s.refine_ms = stage.lap_ms();
    s.splits = r.splits;
    s.merges = r.merges;
    s.refine_waiting = r.waiting;
  }

  if (params_.raycast_every_frame) {
    stage.restart();
    RaycastStats rs;
    // The frame was just fused from this pose: its depth tells each ray where to start.
    const PinholeCamera camera = model_camera();
    const DepthImage* hint = &frame.depth_m;
    if (camera.width != frame.depth_m.width()) {
      const int n = params_.track.model_subsample;
      hint_.resize(camera.width, camera.height);
      for (int y = 0; y < camera.height; ++y)
        for (int x = 0; x < camera.width; ++x)
          hint_(x, y) = frame.depth_m(n * x + n / 2, n * y + n / 2);
      hint = &hint_;
    }
    // Where the frame has no depth, or the search at its depth fails (a depth in front of the
    // model's surface, or on voxels not observed yet), the surface the previous raycast saw, seen
    // from here.
    const RaycastResult& previous = raycaster_.result();
    const DepthImage* fallback = nullptr;
    if (params_.previous_raycast_hints && previous.camera.width == camera.width &&
        previous.camera.height == camera.height && !previous.depth_m.empty()) {
      warp_raycast_depth(previous, camera, T_wc, params_.fusion.truncation_m, &warped_,
                         &warp_scratch_);
      fallback = &warped_;
    }
    raycaster_.raycast(*map_, camera, T_wc, &rs, hint, fallback);
    s.raycast_ms = stage.lap_ms();
    s.raycast_hits = rs.hits;
    s.raycast_hits_at_hint = rs.found_at_hint;
  }
}

PinholeCamera Reconstruction::model_camera() const {
  return info_.depth_camera.subsampled(params_.track.model_subsample);
}

Pose Reconstruction::overview_pose(const PinholeCamera& camera, float* max_depth_m) const {
  // Robust centre and extent of the model: the blocks' centres, trimmed of the farthest 5 %.
  std::vector<Eigen::Vector3d> centres;
  for (const BlockRef& b : map_->allocated_blocks()) {
    const double s = map_->params().block_size_at(b.level);
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

const RaycastResult& Reconstruction::render(const PinholeCamera& camera, const Pose& T_wc,
                                            float max_depth_m) {
  RaycastParams p = raycast_params_for(params_);
  if (max_depth_m > 0.0f) p.max_depth_m = max_depth_m;
  Raycaster raycaster(p);
  raycaster.raycast(*map_, camera, T_wc);
  // Keep the per-frame raycast intact: copy the render out of the temporary raycaster.
  render_result_ = raycaster.result();
  return render_result_;
}

}  // namespace hivox

#include "hivox/synth_mesh/mesh_dataset.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>
#include <Eigen/Geometry>

#include "hivox/core/error.h"

namespace hivox {

void MeshSequenceParams::validate() const {
  camera.validate("mesh sequence: camera");
  noise.validate();
  if (!std::isfinite(max_depth_m) || max_depth_m <= 0.0)
    fail(ErrorCode::InvalidArgument, "mesh sequence: max_depth_m must be > 0, got {}", max_depth_m);
  if (stride == 0) fail(ErrorCode::InvalidArgument, "mesh sequence: stride must be >= 1, got 0");
}

std::string MeshSequenceParams::to_string() const {
  return fmt::format("camera=[{}] max_depth={} m stride={} max_frames={} noise=[{}]",
                     camera.to_string(), max_depth_m, stride,
                     max_frames == 0 ? std::string("all") : std::to_string(max_frames),
                     noise.to_string());
}

MeshDataset::MeshDataset(MeshScene scene, const std::vector<StampedPose>& trajectory_w,
                         MeshSequenceParams params, std::string source)
    : scene_(std::move(scene)), params_(params) {
  params_.validate();
  if (trajectory_w.empty())
    fail(ErrorCode::InvalidArgument, "mesh sequence: the trajectory has no poses");
  for (std::size_t i = 0; i < trajectory_w.size(); i += params_.stride) {
    if (params_.max_frames != 0 && trajectory_.size() == params_.max_frames) break;
    const StampedPose& p = trajectory_w[i];
    if (!std::isfinite(p.timestamp_s) || !p.T_wc.matrix().allFinite())
      fail(ErrorCode::InvalidArgument, "mesh sequence: trajectory pose {} is not finite", i);
    // Frames are named by their timestamps with 6 decimals: two in the same microsecond would
    // be one file.
    if (!trajectory_.empty() &&
        std::llround(p.timestamp_s * 1e6) <= std::llround(trajectory_.back().timestamp_s * 1e6))
      fail(ErrorCode::InvalidArgument,
           "mesh sequence: trajectory pose {} (t = {:.6f} s) is not later than the pose before "
           "it (t = {:.6f} s); timestamps must increase",
           i, p.timestamp_s, trajectory_.back().timestamp_s);
    trajectory_.push_back(p);
  }

  info_.source = std::move(source);
  info_.layout = DatasetLayout::Synthetic;
  info_.layout_reason = "rendered from a mesh";
  info_.frame_count = trajectory_.size();
  info_.rig.depth_camera = params_.camera;
  info_.rig.color_camera = params_.camera;
  info_.intrinsics_source = "given";
  info_.rig.depth_scale = 0;
  info_.depth_scale_source = "metric (rendered)";
  info_.has_color = true;
  info_.has_ground_truth = true;
  info_.ground_truth_count = trajectory_.size();
  info_.first_timestamp_s = trajectory_.front().timestamp_s;
  info_.rig.depth_noise = params_.noise.sensor_noise();
}

RenderedFrame MeshDataset::render_clean(std::size_t index) const {
  if (index >= trajectory_.size())
    fail(ErrorCode::InvalidArgument, "{}: frame {} out of range (0..{})", info_.source, index,
         trajectory_.size() - 1);
  return render(scene_, params_.camera, trajectory_[index].T_wc, params_.max_depth_m);
}

RgbdFrame MeshDataset::read(std::size_t index) {
  RenderedFrame clean = render_clean(index);
  RgbdFrame frame;
  frame.index = index;
  frame.timestamp_s = trajectory_[index].timestamp_s;
  frame.depth_m = apply_noise(clean, params_.camera, params_.noise, index);
  frame.color = std::move(clean.color);
  frame.T_wc_gt = trajectory_[index].T_wc;
  return frame;
}

CameraPath framing_orbit(const Aabb& bounds_w, const PinholeCamera& camera) {
  camera.validate("framing orbit: camera");
  if (bounds_w.empty() || !bounds_w.min_w.allFinite() || !bounds_w.max_w.allFinite())
    fail(ErrorCode::InvalidArgument, "framing orbit: the bounding box is empty or not finite");
  // Half angle of the view to the nearer image border, each axis from the principal point to the
  // outer edge of the last pixel.
  const double half_x = std::min(camera.cx + 0.5, camera.width - 0.5 - camera.cx);
  const double half_y = std::min(camera.cy + 0.5, camera.height - 0.5 - camera.cy);
  const double half_fov_rad =
      std::min(std::atan2(half_x, std::abs(camera.fx)), std::atan2(half_y, std::abs(camera.fy)));
  if (!(half_fov_rad > 0.0))
    fail(ErrorCode::InvalidArgument,
         "framing orbit: the principal point lies outside the image; no view to frame");
  const double radius_m = 0.5 * bounds_w.size().norm();
  CameraPath path;
  path.kind = PathKind::Orbit;
  path.target_w = bounds_w.center();
  // The sphere fits at the nearest point of the path too (a flat or point-like mesh still needs
  // a positive distance).
  path.distance_m = std::max(radius_m, 1e-6) / std::sin(half_fov_rad) / (1.0 - path.distance_swing);
  return path;
}

std::vector<StampedPose> make_trajectory_up(const CameraPath& path, std::size_t frames,
                                            const Eigen::Vector3d& up_w, double fps) {
  if (!up_w.allFinite() || !(up_w.norm() > 0.0))
    fail(ErrorCode::InvalidArgument, "trajectory: the up direction must be finite and non-zero");
  std::vector<StampedPose> poses = make_trajectory(path, frames, fps);
  const Eigen::Matrix3d R =
      Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), up_w.normalized())
          .toRotationMatrix();
  // Turn about the target: p -> target + R (p - target).
  Pose turn = Pose::Identity();
  turn.linear() = R;
  turn.translation() = path.target_w - R * path.target_w;
  for (StampedPose& p : poses) p.T_wc = turn * p.T_wc;
  return poses;
}

}  // namespace hivox

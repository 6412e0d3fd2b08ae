#pragma once
/// @file
/// Frame-to-model camera tracking (DESIGN §6): point-to-plane ICP of a depth frame against the
/// raycast of the model, coarse to fine, with robust weights and a per-frame quality verdict.

#include <cstdint>
#include <vector>

#include "hivox/core/camera.h"
#include "hivox/core/camera_rig.h"
#include "hivox/core/device.h"
#include "hivox/core/image.h"
#include "hivox/core/pose.h"
#include "hivox/raycast/raycaster.h"
#include "hivox/track/params.h"
#include "hivox/track/preprocess.h"

namespace hivox {

namespace icp {
struct Sums;
}

struct TrackResult {
  Pose T_wc = Pose::Identity();  ///< estimated camera-to-world pose (the start pose when lost)
  TrackingQuality quality = TrackingQuality::Lost;
  int64_t valid_pixels = 0;  ///< finest-level pixels with a point and a normal
  int64_t inliers = 0;       ///< finest-level pixels matched to the model in the last iteration
  double inlier_ratio = 0;   ///< inliers / valid_pixels
  double rms_m = 0;          ///< RMS point-to-plane residual of the inliers
  double condition = 0;      ///< smallest / largest eigenvalue of the normalised system (0..1)
  int iterations = 0;        ///< Gauss-Newton iterations run, all levels
  double preprocess_ms = 0;  ///< on a GPU: launching the preprocessing (its kernels end in icp_ms)
  double icp_ms = 0;
};

/// The frame-to-frame flow around tracking, one owner for every loop (CPU and devices): where a
/// frame's tracking starts and which pose it keeps. Tracking starts from the previous pose moved
/// by the last frame-to-frame motion (`TrackParams::constant_velocity`) or from the previous pose
/// itself; a tracked frame keeps its estimate and becomes the motion; a lost frame keeps the
/// previous pose and forgets the motion, as does a frame fused at a given pose.
class MotionPrior {
 public:
  explicit MotionPrior(bool constant_velocity) : constant_velocity_(constant_velocity) {}
  /// Where tracking from `T_prev` (the last frame's pose) starts.
  Pose start(const Pose& T_prev) const {
    return constant_velocity_ ? Pose(T_prev * motion_) : T_prev;
  }
  /// The pose a frame tracked from `T_prev` keeps, given its tracking `result`.
  Pose keep(const Pose& T_prev, const TrackResult& result) {
    if (result.quality == TrackingQuality::Lost) {
      restart();
      return T_prev;
    }
    motion_ = T_prev.inverse() * result.T_wc;
    return result.T_wc;
  }
  /// A frame fused at a given pose (a new map's first): no motion known.
  void restart() { motion_ = Pose::Identity(); }

 private:
  bool constant_velocity_ = true;
  Pose motion_ = Pose::Identity();  ///< the last frame-to-frame motion (camera frame)
};

class Tracker {
 public:
  /// Depths outside `depth_range` are ignored (a reconstruction passes its fusion's range); the
  /// ICP reduction runs on `device`.
  explicit Tracker(const TrackParams& params = {}, const DepthRange& depth_range = {},
                   const Device& device = Device::cpu());
  ~Tracker();
  Tracker(Tracker&&) noexcept;
  Tracker& operator=(Tracker&&) noexcept;
  const TrackParams& params() const { return params_; }
  const DepthRange& depth_range() const { return depth_range_; }

  /// Aligns the depth frame to `model` (a raycast of the map, points and normals in world
  /// coordinates, from the model's own pose and camera) starting at `T_wc_init`. The depth
  /// camera may differ in resolution from the model's.
  TrackResult track(const DepthImage& depth_m, const PinholeCamera& camera,
                    const RaycastResult& model, const Pose& T_wc_init);

  /// Throws `Error(InvalidArgument)` when images of `frame_camera` tracked against a model of
  /// `model_camera` are too small for the pyramid (every level of both needs kMinLevelPx pixels
  /// a side). `track` checks it too; a run checks it before its first frame.
  void check_sizes(const PinholeCamera& frame_camera, const PinholeCamera& model_camera) const;
  static constexpr int kMinLevelPx = 1;

  /// The frame pyramid of the last call (finest first), e.g. for inspection.
  const std::vector<PyramidLevel>& pyramid() const { return frame_; }

 private:
  struct ModelLevel {
    PinholeCamera camera;
    Image<Vec3f> points_w, normals_w;  ///< zero normal where the model has no surface
    DepthImage depth_m;
  };
  struct RowScratch;
  struct RowSums;
  void build_model_pyramid(const RaycastResult& model);
  /// One pass over pyramid level `level` at pose `T`: projective association against the model
  /// and the normal equations (the ICP reduction; dispatches on the device).
  icp::Sums reduce(int level, const Pose& T);
  icp::Sums reduce_cpu(int level, const Pose& T);

  TrackParams params_;
  DepthRange depth_range_;
  Device device_;
  std::vector<PyramidLevel> frame_;
  std::vector<ModelLevel> model_;
  Rigid3f T_model_cw_;               ///< world to the model's camera (this call's)
  std::vector<RowScratch> scratch_;  ///< per thread, kept across passes and frames
  std::vector<RowSums> row_sums_;    ///< per row of the level in a pass
};

}  // namespace hivox

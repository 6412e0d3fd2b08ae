#pragma once
/// @file
/// A ground-truth RGB-D sequence rendered from a triangle mesh along a given trajectory: a
/// `DatasetReader` whose frames are exact renders (`mesh_render.h`), optionally with Kinect-like
/// depth noise (`noise.h`), and whose ground-truth poses are the trajectory's. Export it with
/// `export_tum` to get a TUM RGB-D sequence.

#include <cstddef>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "hivox/core/camera.h"
#include "hivox/core/dataset.h"
#include "hivox/core/pose.h"
#include "hivox/synth/noise.h"
#include "hivox/synth/render.h"
#include "hivox/synth/trajectory.h"
#include "hivox/synth_mesh/mesh_render.h"

namespace hivox {

struct MeshSequenceParams {
  PinholeCamera camera;        ///< the camera rendered through (must be valid)
  NoiseParams noise;           ///< Kinect-like by default; `NoiseParams::none()` for clean depth
  double max_depth_m = 10.0;   ///< rendered depth beyond this is invalid (0)
  std::size_t stride = 1;      ///< frame i is the trajectory's pose i * stride
  std::size_t max_frames = 0;  ///< at most this many frames; 0 = as many as the trajectory gives

  /// Throws `Error(InvalidArgument)` naming the bad field.
  void validate() const;
  std::string to_string() const;
};

class MeshDataset : public DatasetReader {
 public:
  /// The sequence of `scene` seen from every `params.stride`-th pose of `trajectory_w`
  /// (camera-to-world, timestamps in seconds), at most `params.max_frames` of them. `source`
  /// names it (e.g. the mesh file) in `info().source`. Throws `Error(InvalidArgument)` for bad
  /// params, an empty trajectory, a non-finite pose, or timestamps of the chosen poses that do
  /// not increase by at least a microsecond (frames are named by their timestamps).
  MeshDataset(MeshScene scene, const std::vector<StampedPose>& trajectory_w,
              MeshSequenceParams params, std::string source = "mesh");

  const DatasetInfo& info() const override { return info_; }
  /// Renders frame `index`: depth (noisy per `params().noise`, metres), colour, timestamp and
  /// ground-truth pose. Throws `Error(InvalidArgument)` when `index >= size()`.
  RgbdFrame read(std::size_t index) override;
  bool reads_concurrently() const override { return true; }
  /// The noise-free render of frame `index` (depth, colour, world normals, pose).
  RenderedFrame render_clean(std::size_t index) const;

  const MeshSequenceParams& params() const { return params_; }
  const MeshScene& scene() const { return scene_; }
  /// The poses of the frames (the chosen poses of the trajectory), one per frame.
  const std::vector<StampedPose>& trajectory() const { return trajectory_; }

 private:
  MeshScene scene_;
  MeshSequenceParams params_;
  std::vector<StampedPose> trajectory_;
  DatasetInfo info_;
};

/// A closed orbit (`PathKind::Orbit`, the other fields at their defaults) about the centre of
/// `bounds_w` at the distance where the box's bounding sphere just fits the narrower side of
/// `camera`'s view at the path's nearest point (the object fills most of the image), z up. Throws
/// `Error(InvalidArgument)` for an empty or non-finite box.
CameraPath framing_orbit(const Aabb& bounds_w, const PinholeCamera& camera);

/// `frames` poses along `path` (as `make_trajectory`, timestamps i / fps), turned about
/// `path.target_w` so that the path's up direction (+z) becomes `up_w` (for meshes modelled
/// with another axis up). Throws `Error(InvalidArgument)` for a zero or non-finite `up_w`.
std::vector<StampedPose> make_trajectory_up(const CameraPath& path, std::size_t frames,
                                            const Eigen::Vector3d& up_w, double fps = 30.0);

}  // namespace hivox

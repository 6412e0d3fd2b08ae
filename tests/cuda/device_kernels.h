#pragma once
// Runs the host-device kernels of fusion and raycasting on a CUDA device, the simplest way (a
// thread per block, a thread per pixel), so that tests can compare them with the CPU drivers.
// Host code only, on the kernels' plain types (no Eigen: nvcc compiles this header too); the CUDA
// side is device_kernels.cu.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "fusion/fusion_kernels.h"
#include "hivox/core/camera.h"
#include "hivox/core/camera_rig.h"
#include "hivox/core/image.h"
#include "hivox/core/math.h"
#include "hivox/map/voxel_block_map.h"
#include "hivox/raycast/params.h"
#include "raycast/coarse_occupancy.h"
#include "track/gauss_newton.h"

namespace hivox::test {

/// The name of CUDA device 0, or empty when there is none (no driver, no device).
std::string cuda_device_name();

/// A copy of a map on the device: its hash tables, its blocks up to the high-water mark and
/// their metadata. The copy can be read and its voxels updated, not allocated into.
class DeviceMap {
 public:
  /// Copies `host`'s tables and its blocks below its high-water mark.
  explicit DeviceMap(const VoxelBlockMap& host);
  ~DeviceMap();
  DeviceMap(const DeviceMap&) = delete;
  DeviceMap& operator=(const DeviceMap&) = delete;

  const MapView& view() const { return storage_.read; }  ///< device pointers
  const MutableMapView& storage() const { return storage_; }
  int32_t high_water() const { return high_water_; }
  /// The device's voxels (and colours, when the map stores them) and block metadata, blocks
  /// [0, high_water()).
  void download(std::vector<TsdfVoxel>* tsdf, std::vector<ColorVoxel>* color,
                std::vector<BlockMeta>* meta) const;

 private:
  MutableMapView storage_;
  int32_t high_water_ = 0;
  std::vector<void*> buffers_;
};

/// Integrates frame `f` into `blocks` of `map` on the device (one GPU thread per block, running
/// kernels::integrate_block). Returns the kernel's time in ms (the frame's upload excluded).
double integrate_on_device(DeviceMap& map, const std::vector<BlockRef>& blocks,
                           const kernels::DepthFrameView& depth,
                           const kernels::ColorFrameView& color,
                           const kernels::IntegrationConstants& k);

/// Both refinement criteria of blocks `ptrs` of `map` on the device (kernels::block_detail_m
/// with `mu_m`, `min_weight`, `min_samples`, and kernels::block_det_cov with `min_weight`).
void block_criteria_on_device(const DeviceMap& map, const std::vector<int32_t>& ptrs, float mu_m,
                              int min_weight, int min_samples, std::vector<float>* detail_m,
                              std::vector<float>* det_cov);

struct DeviceRaycast {
  std::vector<float> depth_m;
  std::vector<Vec3f> points_w, normals_w;
  std::vector<Rgb8> colors;
  std::vector<int8_t> levels;
  double range_ms = 0;  ///< projecting the blocks into the range tiles
  double rays_ms = 0;   ///< casting the rays
};

/// Raycasts `map` on the device as the CPU driver does without ray packets: range tiles from
/// the projected blocks, then per pixel kernels::cast_ray with the hints (either may be null)
/// and kernels::write_ray. `occupancy` is the coarse occupancy grid of the map on the host
/// (kernels::build_coarse_occupancy; its cells are copied), hints are host images of the
/// camera's size. `repeats` casts (>= 1) are timed; the times are the fastest.
DeviceRaycast raycast_on_device(const DeviceMap& map, const kernels::CoarseOccupancy& occupancy,
                                const RaycastParams& params, const DepthRange& range,
                                const PinholeCamera& camera, const Rigid3f& T_wc,
                                const DepthImage* start_hint_m, const DepthImage* fallback_hint_m,
                                int repeats = 1);

/// Gauss-Newton stepped on the device (one thread, kernels::icp_update) from `start` through the
/// passes `levels[i]` with sums `sums[30 i, 30 i + 30)`, passes at a stopped level skipped
/// (kernels::icp_skips), as the host's align steps it.
kernels::IcpState gauss_newton_on_device(const kernels::PoseD& start,
                                         const std::vector<int>& levels,
                                         const std::vector<double>& sums, double convergence_step);

}  // namespace hivox::test

#include "cuda/device_kernels.h"

#include <cuda_runtime.h>

#include <algorithm>
#include <cfloat>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "core/parallel.h"
#include "fusion/fusion_kernels.h"
#include "map/map_access.h"
#include "raycast/coarse_occupancy.h"
#include "raycast/raycast_kernels.h"
#include "refine/refine_kernels.h"

namespace hivox::test {
namespace {

void check(cudaError_t e, const char* what) {
  if (e != cudaSuccess)
    throw std::runtime_error(std::string("CUDA ") + what + " failed: " + cudaGetErrorString(e));
}

/// A device buffer freed at the end of its scope.
template <typename T>
struct DeviceBuffer {
  T* ptr = nullptr;
  explicit DeviceBuffer(std::size_t n) {
    if (n > 0) check(cudaMalloc(&ptr, n * sizeof(T)), "cudaMalloc");
  }
  DeviceBuffer(const T* host, std::size_t n) : DeviceBuffer(n) {
    if (n > 0) check(cudaMemcpy(ptr, host, n * sizeof(T), cudaMemcpyHostToDevice), "upload");
  }
  ~DeviceBuffer() { cudaFree(ptr); }
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
  void download(T* host, std::size_t n) const {
    if (n > 0) check(cudaMemcpy(host, ptr, n * sizeof(T), cudaMemcpyDeviceToHost), "download");
  }
};

/// Times the launches `launches` makes (ms, on the default stream).
template <typename Launches>
double timed(Launches&& launches) {
  cudaEvent_t start, stop;
  check(cudaEventCreate(&start), "cudaEventCreate");
  check(cudaEventCreate(&stop), "cudaEventCreate");
  check(cudaEventRecord(start), "cudaEventRecord");
  launches();
  check(cudaGetLastError(), "kernel launch");
  check(cudaEventRecord(stop), "cudaEventRecord");
  check(cudaEventSynchronize(stop), "kernel");
  float ms = 0;
  check(cudaEventElapsedTime(&ms, start, stop), "cudaEventElapsedTime");
  cudaEventDestroy(start);
  cudaEventDestroy(stop);
  return ms;
}

__global__ void project_blocks(MapView map, int32_t high_water, Rigid3f T_cw, PinholeCamera cam,
                               float min_depth_m, float max_depth_m, kernels::RangeTiles tiles) {
  const int32_t ptr = blockIdx.x * blockDim.x + threadIdx.x;
  if (ptr >= high_water) return;
  const BlockMeta m = map.meta[ptr];
  if (m.level < 0) return;
  kernels::project_block_to_tiles(T_cw, cam, m.pos, map.level[m.level].block_size_m, min_depth_m,
                                  max_depth_m, tiles);
}

__global__ void fill(float* a, int n, float value) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) a[i] = value;
}

__global__ void cast_rays(MapView map, PinholeCamera cam, Rigid3f T_wc, kernels::RangeTiles tiles,
                          const float* start_hint_m, const float* fallback_hint_m,
                          kernels::RayMarchConstants k, kernels::RaycastOutputView out) {
  const int x = blockIdx.x * blockDim.x + threadIdx.x;
  const int y = blockIdx.y * blockDim.y + threadIdx.y;
  if (x >= cam.width || y >= cam.height) return;
  const int64_t i = static_cast<int64_t>(y) * cam.width + x;
  const int t = tiles.tile_of(x, y);
  const float z_min = tiles.z_min[t], z_max = tiles.z_max[t];
  const kernels::RayHints hints =
      kernels::ray_hints(start_hint_m != nullptr ? start_hint_m[i] : 0.0f,
                         fallback_hint_m != nullptr ? fallback_hint_m[i] : 0.0f, k, z_min, z_max);
  const Vec3f dir = T_wc.rotate(cam.ray(static_cast<float>(x), static_cast<float>(y)));
  kernels::BlockLookupCache cache;
  kernels::RayHit hit;
  const kernels::RayOutcome outcome =
      kernels::cast_ray(map, cache, T_wc.t, dir, hints, z_min, z_max, k, &hit);
  kernels::write_ray(out, map, i, outcome != kernels::RayOutcome::Miss, hit);
}

__global__ void gauss_newton(kernels::IcpState* state, const int* levels, const double* sums,
                             int passes, double convergence_step) {
  for (int i = 0; i < passes; ++i)
    if (!kernels::icp_skips(*state, levels[i]))
      kernels::icp_update(*state, sums + kernels::kIcpSums * i, levels[i], convergence_step);
}

}  // namespace

std::string cuda_device_name() {
  int count = 0;
  if (cudaGetDeviceCount(&count) != cudaSuccess || count == 0) {
    cudaGetLastError();  // clear the error for later calls
    return {};
  }
  cudaDeviceProp prop;
  check(cudaGetDeviceProperties(&prop, 0), "cudaGetDeviceProperties");
  return prop.name;
}

DeviceMap::DeviceMap(const VoxelBlockMap& map)
    : storage_(MapAccess::storage(map)), high_water_(map.block_high_water()) {
  const MutableMapView host = storage_;
  auto upload = [&](const auto* host, std::size_t n) {
    using T = std::remove_const_t<std::remove_pointer_t<decltype(host)>>;
    T* device = nullptr;
    check(cudaMalloc(&device, std::max<std::size_t>(n, 1) * sizeof(T)), "cudaMalloc");
    buffers_.push_back(device);
    if (n > 0) check(cudaMemcpy(device, host, n * sizeof(T), cudaMemcpyHostToDevice), "upload");
    return device;
  };
  for (int l = 0; l < host.read.levels; ++l) {
    storage_.level[l].entries =
        upload(host.level[l].entries, static_cast<std::size_t>(host.read.level[l].entry_count));
    storage_.level[l].excess = {};  // nothing is allocated on the device
    storage_.read.level[l].entries = storage_.level[l].entries;
  }
  const std::size_t voxels = static_cast<std::size_t>(high_water_) * kBlockVoxels;
  storage_.tsdf = upload(host.tsdf, voxels);
  storage_.color = host.color != nullptr ? upload(host.color, voxels) : nullptr;
  storage_.meta = upload(host.meta, static_cast<std::size_t>(high_water_));
  storage_.blocks = {};
  storage_.level_block_count = upload(host.level_block_count, kMaxLevels);
  storage_.block_high_water = upload(host.block_high_water, 1);
  storage_.read.tsdf = storage_.tsdf;
  storage_.read.color = storage_.color;
  storage_.read.meta = storage_.meta;
  storage_.read.block_capacity = high_water_;
}

DeviceMap::~DeviceMap() {
  for (void* b : buffers_) cudaFree(b);
}

void DeviceMap::download(std::vector<TsdfVoxel>* tsdf, std::vector<ColorVoxel>* color,
                         std::vector<BlockMeta>* meta) const {
  const std::size_t voxels = static_cast<std::size_t>(high_water_) * kBlockVoxels;
  tsdf->resize(voxels);
  check(cudaMemcpy(tsdf->data(), storage_.tsdf, voxels * sizeof(TsdfVoxel), cudaMemcpyDeviceToHost),
        "download");
  color->clear();
  if (storage_.color != nullptr) {
    color->resize(voxels);
    check(cudaMemcpy(color->data(), storage_.color, voxels * sizeof(ColorVoxel),
                     cudaMemcpyDeviceToHost),
          "download");
  }
  meta->resize(static_cast<std::size_t>(high_water_));
  check(cudaMemcpy(meta->data(), storage_.meta, meta->size() * sizeof(BlockMeta),
                   cudaMemcpyDeviceToHost),
        "download");
}

double integrate_on_device(DeviceMap& map, const std::vector<BlockRef>& blocks,
                           const kernels::DepthFrameView& d, const kernels::ColorFrameView& c,
                           const kernels::IntegrationConstants& k) {
  DeviceBuffer<float> depth(d.depth_m.data,
                            static_cast<std::size_t>(d.depth_m.width) * d.depth_m.height);
  kernels::DepthFrameView depth_view = d;
  depth_view.depth_m.data = depth.ptr;
  kernels::ColorFrameView color_view = c;
  const std::size_t color_pixels = static_cast<std::size_t>(c.image.width) * c.image.height;
  DeviceBuffer<Rgb8> color(c.image.empty() ? nullptr : c.image.data,
                           c.image.empty() ? 0 : color_pixels);
  DeviceBuffer<uint32_t> packed(c.packed, c.packed != nullptr ? color_pixels : 0);
  color_view.image.data = color.ptr;
  color_view.packed = packed.ptr;
  DeviceBuffer<BlockRef> refs(blocks.data(), blocks.size());
  // The library's launch point with the library's per-block kernel: the loop a CUDA backend runs.
  const MutableMapView view = map.storage();
  const BlockRef* block = refs.ptr;
  return timed([&] {
    parallel_for(Device::cuda(), static_cast<int64_t>(blocks.size()), [=] HIVOX_HD(int64_t i) {
      const BlockRef b = block[i];
      kernels::integrate_block(view, b.level, b.pos, b.ptr, depth_view, color_view, k);
    });
  });
}

void block_criteria_on_device(const DeviceMap& map, const std::vector<int32_t>& ptrs, float mu_m,
                              int min_weight, int min_samples, std::vector<float>* detail_m,
                              std::vector<float>* det_cov) {
  DeviceBuffer<int32_t> device_ptrs(ptrs.data(), ptrs.size());
  DeviceBuffer<float> detail(ptrs.size()), cov(ptrs.size());
  const MapView view = map.view();
  const int32_t* ptr = device_ptrs.ptr;
  float* detail_out = detail.ptr;
  float* cov_out = cov.ptr;
  timed([&] {
    parallel_for(Device::cuda(), static_cast<int64_t>(ptrs.size()), [=] HIVOX_HD(int64_t i) {
      const TsdfVoxel* v = view.tsdf + static_cast<int64_t>(ptr[i]) * kBlockVoxels;
      detail_out[i] = kernels::block_detail_m(v, mu_m, min_weight, min_samples);
      cov_out[i] = kernels::block_det_cov(v, min_weight);
    });
  });
  detail_m->resize(ptrs.size());
  det_cov->resize(ptrs.size());
  detail.download(detail_m->data(), ptrs.size());
  cov.download(det_cov->data(), ptrs.size());
}

DeviceRaycast raycast_on_device(const DeviceMap& map, const kernels::CoarseOccupancy& occupancy,
                                const RaycastParams& params, const DepthRange& range,
                                const PinholeCamera& camera, const Rigid3f& T_wc,
                                const DepthImage* start_hint_m, const DepthImage* fallback_hint_m,
                                int repeats) {
  params.validate();
  const int w = camera.width, h = camera.height;
  const std::size_t pixels = static_cast<std::size_t>(w) * h;
  kernels::RangeTiles tiles = kernels::RangeTiles::covering(params.tuning.range_tile_px, camera);
  const int tile_count = tiles.count();
  DeviceBuffer<float> z_min(static_cast<std::size_t>(tile_count));
  DeviceBuffer<float> z_max(static_cast<std::size_t>(tile_count));
  tiles.z_min = z_min.ptr;
  tiles.z_max = z_max.ptr;

  const std::size_t cell_count =
      occupancy.cells != nullptr
          ? static_cast<std::size_t>(occupancy.dims.x) * occupancy.dims.y * occupancy.dims.z
          : 0;
  DeviceBuffer<int32_t> cells(occupancy.cells, cell_count);
  kernels::CoarseOccupancy device_occupancy = occupancy;
  device_occupancy.cells = occupancy.cells != nullptr ? cells.ptr : nullptr;
  const kernels::RayMarchConstants k =
      kernels::march_constants(params, map.view(), device_occupancy);

  auto upload_hint = [&](const DepthImage* image) {
    return std::make_unique<DeviceBuffer<float>>(image != nullptr ? image->data() : nullptr,
                                                 image != nullptr ? pixels : 0);
  };
  const auto start = upload_hint(start_hint_m), fallback = upload_hint(fallback_hint_m);
  DeviceBuffer<float> depth(pixels);
  DeviceBuffer<Vec3f> points(pixels), normals(pixels);
  DeviceBuffer<Rgb8> colors(pixels);
  DeviceBuffer<int8_t> levels(pixels);
  const kernels::RaycastOutputView out{depth.ptr, points.ptr, normals.ptr, colors.ptr, levels.ptr};

  const Rigid3f T_cw = T_wc.inverse();
  DeviceRaycast result;
  result.range_ms = result.rays_ms = DBL_MAX;
  for (int r = 0; r < std::max(repeats, 1); ++r) {
    result.range_ms = std::min(
        result.range_ms, timed([&] {
          constexpr int kThreads = 256;
          launch(fill, (tile_count + kThreads - 1) / kThreads, kThreads, z_min.ptr, tile_count,
                 FLT_MAX);
          launch(fill, (tile_count + kThreads - 1) / kThreads, kThreads, z_max.ptr, tile_count,
                 0.0f);
          launch(project_blocks, (map.high_water() + kThreads - 1) / kThreads, kThreads, map.view(),
                 map.high_water(), T_cw, camera, range.min_m, range.max_m, tiles);
        }));
    result.rays_ms = std::min(result.rays_ms, timed([&] {
                                const dim3 threads(16, 8);
                                const dim3 grid((w + threads.x - 1) / threads.x,
                                                (h + threads.y - 1) / threads.y);
                                launch(cast_rays, grid, threads, map.view(), camera, T_wc, tiles,
                                       start->ptr, fallback->ptr, k, out);
                              }));
  }
  result.depth_m.resize(pixels);
  result.points_w.resize(pixels);
  result.normals_w.resize(pixels);
  result.colors.resize(pixels);
  result.levels.resize(pixels);
  depth.download(result.depth_m.data(), pixels);
  points.download(result.points_w.data(), pixels);
  normals.download(result.normals_w.data(), pixels);
  colors.download(result.colors.data(), pixels);
  levels.download(result.levels.data(), pixels);
  return result;
}

kernels::IcpState gauss_newton_on_device(const kernels::PoseD& start,
                                         const std::vector<int>& levels,
                                         const std::vector<double>& sums, double convergence_step) {
  kernels::IcpState host = kernels::icp_start(start);
  kernels::IcpState* state = nullptr;
  int* d_levels = nullptr;
  double* d_sums = nullptr;
  check(cudaMalloc(&state, sizeof(host)), "cudaMalloc");
  check(cudaMalloc(&d_levels, levels.size() * sizeof(int)), "cudaMalloc");
  check(cudaMalloc(&d_sums, sums.size() * sizeof(double)), "cudaMalloc");
  check(cudaMemcpy(state, &host, sizeof(host), cudaMemcpyHostToDevice), "upload");
  check(cudaMemcpy(d_levels, levels.data(), levels.size() * sizeof(int), cudaMemcpyHostToDevice),
        "upload");
  check(cudaMemcpy(d_sums, sums.data(), sums.size() * sizeof(double), cudaMemcpyHostToDevice),
        "upload");
  launch(gauss_newton, 1, 1, state, d_levels, d_sums, static_cast<int>(levels.size()),
         convergence_step);
  check(cudaGetLastError(), "gauss_newton");
  check(cudaMemcpy(&host, state, sizeof(host), cudaMemcpyDeviceToHost), "download");
  cudaFree(state);
  cudaFree(d_levels);
  cudaFree(d_sums);
  return host;
}

}  // namespace hivox::test

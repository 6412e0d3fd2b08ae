// The CUDA loop (hivox::cuda::GpuReconstruction) gives what the CPU stages give on the same
// inputs: the same blocks per level, the TSDF within its quantisation, the same raycast, the same
// tracked poses within tolerance. Built with -DHIVOX_WITH_CUDA=ON; skipped without a CUDA device.

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <tuple>
#include <vector>

#include "apps/cli_util.h"
#include "cuda/device_memory.h"
#include "cuda/loop_kernels.h"
#include "hivox/core/error.h"
#include "hivox/core/timer.h"
#include "hivox/cuda/gpu_reconstruction.h"
#include "hivox/eval/trajectory_eval.h"
#include "hivox/fusion/integrator.h"
#include "hivox/io/atomic_file.h"
#include "hivox/io/dataset.h"
#include "hivox/io/image_io.h"
#include "hivox/io/map_file.h"
#include "hivox/io/ply.h"
#include "hivox/mesh/extract_mesh.h"
#include "hivox/pipeline/reconstruction.h"
#include "hivox/raycast/hints.h"
#include "hivox/raycast/raycaster.h"
#include "hivox/raycast/warp.h"
#include "hivox/refine/refiner.h"
#include "hivox/run/devices.h"
#include "hivox/run/runner.h"
#include "hivox/synth/synthetic_dataset.h"
#include "map/map_invariants.h"
#include "mesh/mesh_test_util.h"
#include "test_util.h"

namespace hivox::test {
namespace {

#define HIVOX_REQUIRE_CUDA()                                                          \
  const std::string device = cuda::device_name();                                     \
  if (device.empty()) GTEST_SKIP() << "no CUDA device found; skipping the GPU tests"; \
  std::printf("[ device   ] %s\n", device.c_str())

using Key = std::tuple<int, int, int, int>;  // level, x, y, z

/// How many of a sequence's frames a test runs: `on_a_gpu` on a GPU, `emulated` (fewer) in the
/// CPU emulation of CUDA, where a frame takes about a second: the same code over fewer frames,
/// which keeps .ci/run's emulated stage short. The sequence's motion a frame stays the same.
/// HIVOX_EMULATION_FRAMES=gpu runs the GPU's counts in the emulation too (about twice as long).
std::size_t frames_to_run(std::size_t on_a_gpu, std::size_t emulated) {
#if defined(HIVOX_CUDA_EMULATION)
  const char* asked = std::getenv("HIVOX_EMULATION_FRAMES");
  if (asked == nullptr || *asked == '\0') return emulated;
  if (std::string_view(asked) == "gpu") return on_a_gpu;
  std::fprintf(stderr, "HIVOX_EMULATION_FRAMES=%s: the only value is \"gpu\"\n", asked);
  std::abort();
#else
  static_cast<void>(emulated);
  return on_a_gpu;
#endif
}

std::string fmt_levels(const VoxelBlockMap& map) {
  std::string s;
  for (const int64_t n : map.blocks_per_level()) s += (s.empty() ? "" : " / ") + std::to_string(n);
  return s + " per level";
}

std::map<Key, int32_t> blocks_of(const VoxelBlockMap& map) {
  std::map<Key, int32_t> out;
  for (const BlockRef& b : map.allocated_blocks())
    out[{b.level, b.pos.x, b.pos.y, b.pos.z}] = b.ptr;
  return out;
}

/// Compares two maps block by block and voxel by voxel (pool indices may differ). Maps fused at
/// the same poses agree to the TSDF's quantisation but at a few voxels; maps fused at tracked
/// poses (`tracked`) differ as much as the poses do.
void expect_same_map(const VoxelBlockMap& cpu, const VoxelBlockMap& gpu, const char* what,
                     bool tracked = false) {
  const double unit_m = cpu.params().truncation_m / 32767.0;
  const auto a = blocks_of(cpu), b = blocks_of(gpu);
  int64_t only_cpu = 0, only_gpu = 0, observed = 0, weight_differ = 0, tsdf_far = 0, color_far = 0,
          tsdf_mm = 0, summary_differ = 0;
  for (const auto& [key, ptr] : a) {
    const auto it = b.find(key);
    if (it == b.end()) {
      ++only_cpu;
      continue;
    }
    // The block's surface summary (octants observed, octants with a voxel at or behind the
    // surface), which the raycast and refinement read.
    const BlockSurface& cs = cpu.block_meta(ptr).surface;
    const BlockSurface& gs = gpu.block_meta(it->second).surface;
    summary_differ += cs.observed != gs.observed || cs.surface != gs.surface;
    const TsdfVoxel* c = cpu.block_tsdf(ptr);
    const TsdfVoxel* g = gpu.block_tsdf(it->second);
    const ColorVoxel* cc = cpu.block_color(ptr);
    const ColorVoxel* gc = gpu.block_color(it->second);
    for (int v = 0; v < kBlockVoxels; ++v) {
      if (c[v].weight == 0 && g[v].weight == 0) continue;
      ++observed;
      weight_differ += c[v].weight != g[v].weight;
      // One int16 unit is 1/32767 of the band: float rounding (fused multiply-adds) alone.
      tsdf_far += std::abs(c[v].tsdf - g[v].tsdf) > 1;
      tsdf_mm += std::abs(c[v].tsdf - g[v].tsdf) * unit_m > 1e-3;
      if (cc != nullptr && gc != nullptr)
        color_far += std::abs(cc[v].r - gc[v].r) > 1 || std::abs(cc[v].g - gc[v].g) > 1 ||
                     std::abs(cc[v].b - gc[v].b) > 1 || cc[v].weight != gc[v].weight;
    }
  }
  for (const auto& [key, ptr] : b) only_gpu += a.count(key) == 0;
  std::printf(
      "[ map      ] %s: %zu blocks on the CPU (%s), %lld only on the CPU, %lld only on the GPU; "
      "%lld observed voxels, %lld weights differ, %lld TSDFs more than one unit apart (%lld more "
      "than 1 mm), %lld colours differ, %lld blocks' surface summaries differ\n",
      what, a.size(), fmt_levels(cpu).c_str(), static_cast<long long>(only_cpu),
      static_cast<long long>(only_gpu), static_cast<long long>(observed),
      static_cast<long long>(weight_differ), static_cast<long long>(tsdf_far),
      static_cast<long long>(tsdf_mm), static_cast<long long>(color_far),
      static_cast<long long>(summary_differ));
  ASSERT_GT(a.size(), 1000u);
  // A summary changes only where a voxel's sign or observation does (rounding, as below); one
  // voxel of a block's 512 is enough, so the bound is looser than the voxels' (0 blocks differ
  // in the emulation; a summary built wrong makes most of them differ).
  EXPECT_LE(summary_differ, static_cast<int64_t>(a.size() / (tracked ? 20 : 100)));
  // A band's end rounded across a block face can add or miss a block at a few pixels.
  EXPECT_LE(only_cpu + only_gpu, static_cast<int64_t>(a.size() / 1000));
  for (int l = 0; l < cpu.levels(); ++l)
    EXPECT_NEAR(cpu.blocks_per_level()[l], gpu.blocks_per_level()[l],
                1 + cpu.blocks_per_level()[l] / 1000)
        << "level " << l;
  if (tracked) {
    // Poses ~0.1 mm apart move the band's edges (weights) and every value a little.
    EXPECT_LE(weight_differ, observed / 20);
    EXPECT_LE(tsdf_mm, observed / 200);
    return;
  }
  // Rounding tips a decision (the bilinear depth's step test, the band's edge) at a few voxels,
  // and a voxel that differed keeps differing over the frames: up to ~6e-4 of them where the CPU
  // build has no fused multiply-adds (HIVOX_NATIVE_ARCH=OFF) and the GPU has.
  EXPECT_LE(weight_differ, observed / 1000);
  EXPECT_LE(tsdf_far, observed / 1000);
  EXPECT_LE(tsdf_mm, observed / 5000);
  EXPECT_LE(color_far, observed / 1000);
}

/// How far two trajectories' matching poses get apart: the largest translation and rotation.
struct PoseGap {
  double max_m = 0, max_deg = 0;
  void add(const Pose& a, const Pose& b) {
    const Pose d = a.inverse() * b;
    max_m = std::max(max_m, d.translation().norm());
    max_deg = std::max(max_deg, rotation_angle_rad(d) * 180.0 / 3.14159265358979);
  }
};

/// The pixels a raycast hit.
int64_t hit_count(const RaycastResult& r) {
  return std::count_if(r.depth_m.data(), r.depth_m.data() + r.depth_m.size(),
                       [](float z) { return z > 0.0f; });
}

/// Whether two raycasts have the same depth at every pixel, to the bit.
bool same_depths(const RaycastResult& a, const RaycastResult& b) {
  return a.depth_m.size() == b.depth_m.size() &&
         std::equal(a.depth_m.data(), a.depth_m.data() + a.depth_m.size(), b.depth_m.data());
}

/// What a device run leaves: its map as its file's bytes (the file holds the blocks in a
/// canonical order, whatever pool blocks they took), its last model raycast and its poses.
struct DeviceResult {
  std::string map_file;
  RaycastResult model;
  std::vector<StampedPose> trajectory;
};
DeviceResult device_result(const cuda::GpuReconstruction& gpu, const ReconstructionParams& p) {
  test::TempDir dir;
  const std::filesystem::path file = dir.path() / "map.hvx";
  write_map_file(file, *gpu.download_map(), p.fusion, MapSession{});
  return {test::file_bytes(file), gpu.download_model(), gpu.trajectory()};
}
/// Two runs that must agree to the bit: the same map, model and poses.
void expect_same_results(const DeviceResult& a, const DeviceResult& b) {
  EXPECT_TRUE(a.map_file == b.map_file) << "the maps";
  EXPECT_TRUE(same_depths(a.model, b.model)) << "the models";
  ASSERT_EQ(a.trajectory.size(), b.trajectory.size());
  for (std::size_t i = 0; i < a.trajectory.size(); ++i)
    EXPECT_TRUE(a.trajectory[i].T_wc.matrix() == b.trajectory[i].T_wc.matrix()) << "frame " << i;
}

/// An environment variable set while it lives, unset after.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const char* value) : name_(name) { setenv(name, value, 1); }
  ~ScopedEnv() { unsetenv(name_); }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  const char* name_;
};

/// The GPU's model raycast against the CPU's raycast of the CPU map at the same pose.
void expect_same_raycast(const RaycastResult& cpu, const RaycastResult& gpu) {
  ASSERT_EQ(cpu.depth_m.width(), gpu.depth_m.width());
  ASSERT_EQ(cpu.depth_m.height(), gpu.depth_m.height());
  int64_t both = 0, only_one = 0, depth_far = 0, normal_far = 0;
  for (int y = 0; y < cpu.depth_m.height(); ++y) {
    for (int x = 0; x < cpu.depth_m.width(); ++x) {
      const bool c = cpu.hit(x, y), g = gpu.hit(x, y);
      only_one += c != g;
      if (!c || !g) continue;
      ++both;
      depth_far += std::abs(cpu.depth_m(x, y) - gpu.depth_m(x, y)) > 1e-3f;
      const Vec3f& a = cpu.normals_w(x, y);
      const Vec3f& b = gpu.normals_w(x, y);
      normal_far += a.x * b.x + a.y * b.y + a.z * b.z < std::cos(2.0f * 3.14159265f / 180.0f);
    }
  }
  std::printf(
      "[ raycast  ] %lld hits, %lld hit by one only, %lld depths > 1 mm apart, %lld normals > 2 "
      "deg apart\n",
      static_cast<long long>(both), static_cast<long long>(only_one),
      static_cast<long long>(depth_far), static_cast<long long>(normal_far));
  ASSERT_GT(both, 10000);
  EXPECT_LE(only_one, both / 200);
  EXPECT_LE(depth_far, both / 200);
  EXPECT_LE(normal_far, both / 200);
}

/// The meshes of the two maps (extract_mesh, default settings): nearly the same triangles.
void expect_same_mesh(const VoxelBlockMap& cpu, const VoxelBlockMap& gpu) {
  const TriangleMesh a = extract_mesh(cpu), b = extract_mesh(gpu);
  auto centroid = [](const TriangleMesh& m) {
    double x = 0, y = 0, z = 0;
    for (const Vec3f& p : m.positions_w) {
      x += p.x;
      y += p.y;
      z += p.z;
    }
    const double n = static_cast<double>(std::max<int64_t>(m.vertex_count(), 1));
    return std::array<double, 3>{x / n, y / n, z / n};
  };
  const std::array<double, 3> ca = centroid(a), cb = centroid(b);
  const double shift =
      std::sqrt((ca[0] - cb[0]) * (ca[0] - cb[0]) + (ca[1] - cb[1]) * (ca[1] - cb[1]) +
                (ca[2] - cb[2]) * (ca[2] - cb[2]));
  std::printf("[ mesh     ] %lld / %lld triangles (CPU / GPU map), centroids %.3f mm apart\n",
              static_cast<long long>(a.triangle_count()),
              static_cast<long long>(b.triangle_count()), 1e3 * shift);
  ASSERT_GT(a.triangle_count(), 10000);
  EXPECT_NEAR(static_cast<double>(b.triangle_count()), static_cast<double>(a.triangle_count()),
              0.01 * static_cast<double>(a.triangle_count()));
  EXPECT_LT(shift, 1e-3);
}

/// The GPU's model raycast (after fusing `frame` at `T_wc`) against the CPU's raycast of
/// `cpu_map` from there, with the hints the GPU takes: the frame's depth, and the GPU's previous
/// raycast `previous` warped into this view (the CPU's warp: the device's is tested with it).
void expect_same_model(const VoxelBlockMap& cpu_map, const RaycastResult& gpu_model,
                       const RaycastResult& previous, const RgbdFrame& frame, const Pose& T_wc,
                       const ReconstructionParams& p, const CameraRig& rig) {
  Raycaster raycaster(p.raycast);
  FrameHints hints;
  expect_same_raycast(
      raycaster.raycast(cpu_map, gpu_model.camera, T_wc, p.fusion.depth_range,
                        hints.build(frame.depth_m, rig.depth_camera, p.track.model_subsample, T_wc,
                                    &previous, p.map.truncation_m)),
      gpu_model);
}

ReconstructionParams params_for(int levels, float voxel_m, float truncation_m) {
  ReconstructionParams p;
  p.device = Device::cuda();
  p.map.levels = levels;
  p.map.voxel_size_m = voxel_m;
  p.map.truncation_m = truncation_m;
  p.map.max_blocks = 1 << 18;
  p.map.buckets_per_level = 1 << 18;
  p.map.excess_per_level = 1 << 17;
  return p;
}

/// The GPU loop's opt-ins (GpuReconstruction's set_split_marches, set_raycast_registers,
/// set_allocation_pixels).
struct DeviceOptions {
  int split_marches = 0;
  int raycast_registers = 0;
  int allocation_pixels = 1;
};

/// Fuses `first` frames on the CPU (refining between frames when the map has several levels),
/// hands the map to the GPU, then fuses (and refines) frames [first, last) at their true poses
/// on both, the GPU with options `o`.
void compare_fusion(const std::string& spec, int levels, float voxel_m, float truncation_m,
                    std::size_t first, std::size_t last, const DeviceOptions& o = {}) {
  const int raycast_registers = o.raycast_registers;
  SyntheticDataset data(parse_synthetic_spec(spec));
  const CameraRig& rig = data.info().rig;
  const ReconstructionParams p = params_for(levels, voxel_m, truncation_m);
  VoxelBlockMap map(p.map);
  TsdfIntegrator integrator(p.fusion);
  Refiner refiner(p.refine, rig.depth_noise);
  for (std::size_t i = 0; i < first; ++i) {
    const RgbdFrame f = data.read(i);
    const Allocation a = integrator.fuse(map, fusion_input(rig, f, *f.T_wc_gt));
    if (levels > 1) refiner.refine(map, a.visible_blocks, *f.T_wc_gt);
  }
  cuda::GpuReconstruction gpu(p, rig, map);
  gpu.set_split_marches(o.split_marches);
  gpu.set_raycast_registers(raycast_registers);
  gpu.set_allocation_pixels(o.allocation_pixels);
  const int registers = gpu.raycast_registers();
  std::printf("[ raycast  ] its kernel takes %d registers a thread (at most %d asked)\n", registers,
              raycast_registers);
  if (raycast_registers > 0) {
    EXPECT_LE(registers, raycast_registers) << "0 in the emulation";
  }
  // From the handover on both refine, counting their calls from there.
  Refiner after(p.refine, rig.depth_noise);
  Pose last_pose = Pose::Identity();
  RaycastResult previous;  // the GPU's raycast before the last frame
  for (std::size_t i = first; i < last; ++i) {
    if (i == last - 1) previous = gpu.download_model();
    const RgbdFrame f = data.read(i);
    const Allocation a = integrator.fuse(map, fusion_input(rig, f, *f.T_wc_gt));
    if (levels > 1) after.refine(map, a.visible_blocks, *f.T_wc_gt);
    const FrameStats& s = gpu.integrate(f, *f.T_wc_gt);
    EXPECT_EQ(s.dropped_blocks, 0);
    // The stages timed by marks in the device's queue took time, in order, within the frame.
    EXPECT_GE(s.allocate_ms, 0.0);
    EXPECT_GT(s.integrate_ms, 0.0);
    EXPECT_LE(s.allocate_ms + s.integrate_ms, s.total_ms);
    last_pose = *f.T_wc_gt;
  }
  const std::unique_ptr<VoxelBlockMap> downloaded = gpu.download_map();
  EXPECT_EQ(downloaded->blocks_in_use(), gpu.blocks_in_use());
  expect_same_map(map, *downloaded, spec.c_str());
  expect_same_mesh(map, *downloaded);

  expect_same_model(map, gpu.download_model(), previous, data.read(last - 1), last_pose, p, rig);
}

TEST(GpuLoop, FusesTheCpusMapOnAFixedGrid) {
  HIVOX_REQUIRE_CUDA();
  compare_fusion("synthetic:desk?frames=30&noise=kinect", 1, 0.005f, 0.02f, 0,
                 frames_to_run(30, 18));
}

TEST(GpuLoop, FusesIntoAHierarchyHandedOverByTheCpu) {
  HIVOX_REQUIRE_CUDA();
  compare_fusion("synthetic:desk?frames=40&noise=kinect", 3, 0.002f, 0.024f, 25,
                 frames_to_run(40, 33));
}

// The model raycast with every warp's marches split across its lanes (the split taken even where
// all 32 rays march) finds what the CPU's whole marches find.
TEST(GpuLoop, SplitMarchesRaycastAsTheCpuDoes) {
  HIVOX_REQUIRE_CUDA();
  compare_fusion("synthetic:desk?frames=40&noise=kinect", 3, 0.002f, 0.024f, 25,
                 frames_to_run(40, 33), {.split_marches = 32});
}

// The model raycast as two kernels, the rays whose search at their hints fails queued and each
// marched across a warp's lanes by the second, casts the rays one kernel casts with every
// warp's marches split (SplitMarchesRaycastAsTheCpuDoes holds those to the CPU's): tracked with
// each, the same poses, map and model to the bit. On the desk about 800 to 3100 rays a frame
// march (the test fails with all but the first queued ray left unmarched: checked).
TEST(GpuLoop, QueuedMarchesCastWhatSplitMarchesCast) {
  HIVOX_REQUIRE_CUDA();
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=40&noise=kinect"));
  const CameraRig& rig = data.info().rig;
  const ReconstructionParams p = params_for(3, 0.002f, 0.024f);
  const Pose first = *data.read(0).T_wc_gt;
  std::vector<DeviceResult> results;
  for (const bool queued : {false, true}) {
    SCOPED_TRACE(queued ? "queued" : "split");
    cuda::GpuReconstruction gpu(p, rig);
    gpu.set_split_marches(32);
    gpu.set_queued_marches(queued);
    for (std::size_t i = 0; i < frames_to_run(data.size(), 8); ++i) {
      const FrameStats& s = gpu.track_and_integrate(data.read(i), first);
      EXPECT_TRUE(s.fused) << "frame " << i;
    }
    results.push_back(device_result(gpu, p));
    EXPECT_GT(hit_count(results.back().model), 10000);
  }
  expect_same_results(results[1], results[0]);
}

// The model raycast's kernel capped at 64 registers a thread (the most spilled of its builds)
// finds what the CPU finds.
TEST(GpuLoop, RaycastsAsTheCpuDoesWithItsRegistersCapped) {
  HIVOX_REQUIRE_CUDA();
#if defined(HIVOX_CUDA_EMULATION)
  GTEST_SKIP() << "the emulation has no registers to cap: its capped kernel is the one "
                  "FusesIntoAHierarchyHandedOverByTheCpu runs; a GPU runs this test";
#endif
  compare_fusion("synthetic:desk?frames=40&noise=kinect", 3, 0.002f, 0.024f, 25,
                 frames_to_run(40, 33), {.raycast_registers = 64});
}

// Allocation threads that walk 2x2 pixels each (skipping the look-ups of blocks seen) find the
// CPU's blocks in a hierarchy, and 2x1 ones too. (On the H200 both printed the very counts of
// FusesIntoAHierarchyHandedOverByTheCpu's one pixel a thread: 196 weights and 1040 TSDFs apart.)
TEST(GpuLoop, AllocatesAsTheCpuDoesWithSeveralPixelsAThread) {
  HIVOX_REQUIRE_CUDA();
  compare_fusion("synthetic:desk?frames=40&noise=kinect", 3, 0.002f, 0.024f, 25,
                 frames_to_run(40, 33), {.allocation_pixels = 4});
  compare_fusion("synthetic:desk?frames=34&noise=kinect", 3, 0.002f, 0.024f, 25,
                 frames_to_run(34, 30), {.allocation_pixels = 2});
}

// However many pixels an allocation thread walks, a frame's blocks are the same set (listed in
// another order, their pool blocks taken in another order): on a fixed grid from an empty map,
// the map (its file holds the blocks in a canonical order) and the model to the bit. The CPU is
// not the reference here: fused from scratch over 12 frames, the device's fused multiply-adds
// alone put 1.2e-3 of the TSDFs more than one unit from the CPU's (H200), beyond
// expect_same_map's bound, which the longer FusesTheCpusMapOnAFixedGrid holds to.
TEST(GpuLoop, SeveralPixelsAThreadAllocateWhatOnePixelDoes) {
  HIVOX_REQUIRE_CUDA();
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=12&noise=kinect"));
  const CameraRig& rig = data.info().rig;
  const ReconstructionParams p = params_for(1, 0.005f, 0.02f);
  std::vector<DeviceResult> results;
  std::vector<int64_t> valid_pixels;
  for (const int pixels : {1, 2, 4}) {
    SCOPED_TRACE(fmt::format("{} pixels a thread", pixels));
    cuda::GpuReconstruction gpu(p, rig);
    gpu.set_allocation_pixels(pixels);
    int64_t valid = 0, fresh = 0;
    for (std::size_t i = 0; i < frames_to_run(data.size(), 6); ++i) {
      const RgbdFrame f = data.read(i);
      const FrameStats& s = gpu.integrate(f, *f.T_wc_gt);
      EXPECT_EQ(s.dropped_blocks, 0) << "frame " << i;
      valid += s.valid_pixels;
      fresh += s.new_blocks;
    }
    std::printf("[ alloc    ] %d pixels a thread: %lld valid pixels, %lld blocks made\n", pixels,
                static_cast<long long>(valid), static_cast<long long>(fresh));
    EXPECT_GT(gpu.blocks_in_use(), 10000);
    results.push_back(device_result(gpu, p));
    valid_pixels.push_back(valid);
  }
  for (std::size_t i = 1; i < results.size(); ++i) {
    SCOPED_TRACE(fmt::format("{} and 1 pixel a thread", i == 1 ? 2 : 4));
    EXPECT_EQ(valid_pixels[i], valid_pixels[0]);
    expect_same_results(results[i], results[0]);
  }
}

// The pool as one plain allocation of its whole capacity (HIVOX_CUDA_VIRTUAL_MEMORY=off, as on a
// driver without virtual memory management) against the pool committed as it grows: the same map
// file and model to the bit over frames that split and merge, with the whole capacity held from
// the start in the one and not in the other.
TEST(GpuLoop, ThePoolAsOnePlainAllocationGivesWhatTheGrowingPoolGives) {
  HIVOX_REQUIRE_CUDA();
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=12&noise=kinect"));
  const CameraRig& rig = data.info().rig;
  ReconstructionParams p = params_for(3, 0.002f, 0.024f);
  p.map.max_blocks = 1 << 16;
  // A block's voxels and colours: what the whole capacity takes at least.
  const int64_t capacity_bytes = int64_t{p.map.max_blocks} * kBlockVoxels *
                                 static_cast<int64_t>(sizeof(TsdfVoxel) + sizeof(ColorVoxel));
  std::vector<DeviceResult> results;
  for (const bool plain : {false, true}) {
    SCOPED_TRACE(plain ? "one plain allocation" : "committed as it grows");
    std::unique_ptr<cuda::GpuReconstruction> gpu;
    {
      const ScopedEnv setting("HIVOX_CUDA_VIRTUAL_MEMORY", plain ? "off" : "on");
      gpu = std::make_unique<cuda::GpuReconstruction>(p, rig);
    }
    int64_t splits = 0, merges = 0;
    for (std::size_t i = 0; i < frames_to_run(data.size(), 6); ++i) {
      const RgbdFrame f = data.read(i);
      const FrameStats& s = gpu->integrate(f, *f.T_wc_gt);
      splits += s.splits;
      merges += s.merges;
    }
    std::printf("[ pool     ] %s: %lld blocks, %lld splits, %lld merges, the map %.1f MiB\n",
                plain ? "one allocation" : "growing", static_cast<long long>(gpu->blocks_in_use()),
                static_cast<long long>(splits), static_cast<long long>(merges),
                static_cast<double>(gpu->map_memory_bytes()) / 1048576.0);
    EXPECT_GT(splits, 0);
    if (plain) {
      EXPECT_GE(gpu->map_memory_bytes(), capacity_bytes);
    } else {
      EXPECT_LT(gpu->map_memory_bytes(), capacity_bytes / 2);
    }
    results.push_back(device_result(*gpu, p));
  }
  expect_same_results(results[0], results[1]);
}

// HIVOX_CUDA_VIRTUAL_MEMORY takes on or off; anything else is refused, naming it.
TEST(GpuLoop, AVirtualMemorySettingNotOnOrOffIsRefused) {
  HIVOX_REQUIRE_CUDA();
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=1"));
  const ScopedEnv setting("HIVOX_CUDA_VIRTUAL_MEMORY", "maybe");
  std::string message;
  try {
    cuda::GpuReconstruction gpu(params_for(1, 0.005f, 0.02f), data.info().rig);
  } catch (const Error& e) {
    message = e.what();
  }
  EXPECT_NE(message.find("HIVOX_CUDA_VIRTUAL_MEMORY=maybe"), std::string::npos) << message;
}

TEST(GpuLoop, TracksAsTheCpuDoes) {
  HIVOX_REQUIRE_CUDA();
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=40&noise=kinect"));
  const CameraRig& rig = data.info().rig;
  ReconstructionParams p = params_for(1, 0.004f, 0.016f);
  cuda::GpuReconstruction gpu(p, rig);
  p.device = Device::cpu();
  Reconstruction cpu(p, rig);
  std::vector<StampedPose> gt;
  const Pose first = *data.read(0).T_wc_gt;
  int64_t model_hits = 0;  // of the model raycast after the frame before
  for (std::size_t i = 0; i < frames_to_run(data.size(), 24); ++i) {
    const RgbdFrame f = data.read(i);
    gt.push_back({f.timestamp_s, *f.T_wc_gt});
    cpu.track_and_integrate(f, 0.0, first);
    const FrameStats& s = gpu.track_and_integrate(f, first);
    EXPECT_TRUE(s.fused) << "frame " << i;
    // A frame reports the raycast it waited for: the one after the frame before, which its
    // tracking used (none for the first).
    EXPECT_EQ(s.raycast_hits, model_hits) << "frame " << i;
    EXPECT_EQ(s.raycast_ms > 0, i > 0) << "frame " << i;
    model_hits = hit_count(gpu.download_model());
  }
  PoseGap gap;
  for (std::size_t i = 0; i < gt.size(); ++i)
    gap.add(cpu.trajectory()[i].T_wc, gpu.trajectory()[i].T_wc);
  const double ate_cpu = evaluate_ate(gt, cpu.trajectory()).rmse_m;
  const double ate_gpu = evaluate_ate(gt, gpu.trajectory()).rmse_m;
  std::printf(
      "[ track    ] %zu frames: poses at most %.3f mm and %.4f deg apart; ATE CPU %.2f mm, GPU "
      "%.2f mm\n",
      gt.size(), 1e3 * gap.max_m, gap.max_deg, 1e3 * ate_cpu, 1e3 * ate_gpu);
  EXPECT_LT(gap.max_m, 1e-3);
  EXPECT_LT(gap.max_deg, 0.1);
  EXPECT_LT(ate_gpu, 0.01);
  const std::unique_ptr<VoxelBlockMap> downloaded = gpu.download_map();
  expect_same_map(cpu.map(), *downloaded, "tracked desk, fixed 4 mm", true);
}

/// Gauss-Newton stepped on the device (every pass launched at once, the state read back once a
/// frame) against the host's stepping of the same sums: the same increments and verdicts, poses
/// equal to the float pose's rounding (the device's double sin and cos differ in the last bits).
/// And the device's passes recorded once as a CUDA graph and replayed every frame
/// (set_tracking_graph): the launches one by one's poses and iteration counts (the same
/// arithmetic on the same sums; the graph's pass kernel reads the model's pose from memory, a
/// build of its own, so within 1 µm rather than to the bit).
TEST(GpuLoop, GaussNewtonOnTheDeviceTracksAsOnTheHost) {
  HIVOX_REQUIRE_CUDA();
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=40&noise=kinect"));
  const CameraRig& rig = data.info().rig;
  const ReconstructionParams p = params_for(3, 0.002f, 0.024f);
  cuda::GpuReconstruction host(p, rig), on_device(p, rig), graph(p, rig);
  host.set_gauss_newton_on_device(false);
  graph.set_tracking_graph(true);
  const Pose first = *data.read(0).T_wc_gt;
  int64_t iterations_differ = 0, verdicts_differ = 0, graph_iterations_differ = 0;
  PoseGap gap;
  const std::size_t frames = frames_to_run(data.size(), 24);
  const std::size_t graph_frames = frames_to_run(frames, 12);
  for (std::size_t i = 0; i < frames; ++i) {
    const RgbdFrame f = data.read(i);
    const FrameStats& a = host.track_and_integrate(f, first);
    const FrameStats& b = on_device.track_and_integrate(f, first);
    EXPECT_TRUE(b.fused) << "frame " << i;
    iterations_differ += a.track_iterations != b.track_iterations;
    verdicts_differ += host.last_track().quality != on_device.last_track().quality;
    gap.add(host.trajectory().back().T_wc, on_device.trajectory().back().T_wc);
    if (i >= graph_frames) continue;
    const FrameStats& g = graph.track_and_integrate(f, first);
    graph_iterations_differ += g.track_iterations != b.track_iterations;
    const Pose& tb = on_device.trajectory().back().T_wc;
    const Pose& tg = graph.trajectory().back().T_wc;
    EXPECT_LT((tb.matrix() - tg.matrix()).cwiseAbs().maxCoeff(), 1e-6)
        << "frame " << i << ", as a graph: " << (tb.translation() - tg.translation()).norm() * 1e3
        << " mm apart";
  }
  EXPECT_LE(graph_iterations_differ, 1);
  std::printf(
      "[ track    ] %zu frames, Gauss-Newton on the device against the host: poses at most %.4f "
      "mm and %.5f deg apart, %lld frames with other iteration counts\n",
      frames, 1e3 * gap.max_m, gap.max_deg, static_cast<long long>(iterations_differ));
  EXPECT_GT(on_device.frames().back().track_iterations, 0);
  EXPECT_EQ(verdicts_differ, 0);
  EXPECT_LE(iterations_differ, 2);
  EXPECT_LT(gap.max_m, 1e-4);
  EXPECT_LT(gap.max_deg, 0.01);
}

TEST(GpuLoop, WarpsARaycastAsTheCpuDoes) {
  HIVOX_REQUIRE_CUDA();
  // A raycast of the desk fused on the CPU, seen from 3 cm and 3 degrees away: the device's warp
  // (the fallback hints of its raycasts) against warp_raycast_depth.
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=6"));
  const CameraRig& rig = data.info().rig;
  const ReconstructionParams p = params_for(1, 0.004f, 0.02f);
  VoxelBlockMap map(p.map);
  TsdfIntegrator integrator(p.fusion);
  Pose T_wc = Pose::Identity();
  for (std::size_t i = 0; i < data.size(); ++i) {
    const RgbdFrame f = data.read(i);
    integrator.fuse(map, fusion_input(rig, f, *f.T_wc_gt));
    T_wc = *f.T_wc_gt;
  }
  const PinholeCamera cam = rig.depth_camera.subsampled(2);
  Raycaster raycaster(p.raycast);
  const RaycastResult r = raycaster.raycast(map, cam, T_wc, p.fusion.depth_range);
  Pose moved = T_wc;
  moved.translate(Eigen::Vector3d(0.03, -0.01, 0.0));
  moved.rotate(Eigen::AngleAxisd(3.0 * M_PI / 180.0, Eigen::Vector3d(0.3, 1.0, 0.0).normalized()));
  DepthImage expected;
  warp_raycast_depth(r, cam, moved, p.map.truncation_m, &expected);

  const auto n = static_cast<std::size_t>(cam.width) * cam.height;
  int64_t bytes = 0;
  cuda::Buffer<float> depth, out;
  cuda::Buffer<Vec3f> points, normals;
  cuda::Buffer<uint32_t> nearest;
  depth.reset(n, &bytes);
  points.reset(n, &bytes);
  normals.reset(n, &bytes);
  nearest.reset(n, &bytes);
  out.reset(n, &bytes);
  depth.upload(r.depth_m.data(), n);
  points.upload(r.points_w.data(), n);
  normals.upload(r.normals_w.data(), n);
  const kernels::WarpView view =
      kernels::WarpView::of(to_rigid3f(moved.inverse()), cam, p.map.truncation_m);
  cuda::warp_depth(view, depth.get(), points.get(), normals.get(), static_cast<int64_t>(n),
                   nearest.get(), out.get());
  std::vector<float> got(n);
  out.download(got.data(), n);
  int64_t with_depth = 0, differ = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const float a = expected.data()[i], b = got[i];
    with_depth += a > 0.0f;
    differ += (a > 0.0f) != (b > 0.0f) || std::abs(a - b) > 1e-5f * a;
  }
  std::printf("[ warp     ] %lld pixels with a warped depth, %lld differ\n",
              static_cast<long long>(with_depth), static_cast<long long>(differ));
  ASSERT_GT(with_depth, static_cast<int64_t>(n / 2));
  // Rounding (the GPU's fused multiply-adds) can move a landing across a pixel's edge.
  EXPECT_LE(differ, with_depth / 1000);
}

/// The same splits and merges on the CPU and the device but where rounding tips a decision at a
/// threshold, so the same blocks per level within a little; the device's map keeps the
/// hierarchy's invariants.
void expect_same_refinement(int64_t cpu_splits, int64_t gpu_splits, int64_t cpu_merges,
                            int64_t gpu_merges, const VoxelBlockMap& cpu,
                            const VoxelBlockMap& gpu) {
  ASSERT_GT(cpu_splits, 100);
  EXPECT_NEAR(static_cast<double>(gpu_splits), static_cast<double>(cpu_splits), 0.02 * cpu_splits);
  EXPECT_NEAR(static_cast<double>(gpu_merges), static_cast<double>(cpu_merges),
              2.0 + 0.05 * cpu_merges);
  const std::vector<int64_t> a = cpu.blocks_per_level(), b = gpu.blocks_per_level();
  for (int l = 0; l < 3; ++l)
    EXPECT_NEAR(static_cast<double>(b[l]), static_cast<double>(a[l]), 10.0 + 0.02 * a[l])
        << "level " << l;
  SCOPED_TRACE("the device's map after splits and merges");
  test::expect_hierarchy_consistent(gpu);
}

/// Fusing at the true poses with refinement on both: the same splits and merges but where
/// rounding tips a decision at a threshold, so the same blocks per level within a little.
TEST(GpuLoop, RefinesAsTheCpuDoes) {
  HIVOX_REQUIRE_CUDA();
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=40&noise=kinect"));
  const CameraRig& rig = data.info().rig;
  ReconstructionParams p = params_for(3, 0.002f, 0.024f);
  cuda::GpuReconstruction gpu(p, rig);
  p.device = Device::cpu();
  Reconstruction cpu(p, rig);
  int64_t cpu_splits = 0, cpu_merges = 0, gpu_splits = 0, gpu_merges = 0;
  RaycastResult previous;  // the GPU's raycast before the last frame
  const std::size_t frames = frames_to_run(data.size(), 28);
  for (std::size_t i = 0; i < frames; ++i) {
    if (i + 1 == frames) previous = gpu.download_model();
    const RgbdFrame f = data.read(i);
    const FrameStats& c = cpu.integrate(f, *f.T_wc_gt);
    const FrameStats& g = gpu.integrate(f, *f.T_wc_gt);
    cpu_splits += c.splits;
    cpu_merges += c.merges;
    gpu_splits += g.splits;
    gpu_merges += g.merges;
  }
  const std::unique_ptr<VoxelBlockMap> downloaded = gpu.download_map();
  std::printf(
      "[ refine   ] splits %lld / %lld, merges %lld / %lld (CPU / GPU); blocks per level "
      "%s / %s\n",
      static_cast<long long>(cpu_splits), static_cast<long long>(gpu_splits),
      static_cast<long long>(cpu_merges), static_cast<long long>(gpu_merges),
      fmt_levels(cpu.map()).c_str(), fmt_levels(*downloaded).c_str());
  expect_same_refinement(cpu_splits, gpu_splits, cpu_merges, gpu_merges, cpu.map(), *downloaded);
  EXPECT_EQ(downloaded->blocks_in_use(), gpu.blocks_in_use());
  expect_same_mesh(cpu.map(), *downloaded);
  const RgbdFrame last = data.read(frames - 1);
  expect_same_model(cpu.map(), gpu.download_model(), previous, last, *last.T_wc_gt, p, rig);
}

/// Refinement after the model raycast (ReconstructionParams::refine_after_raycast): the device
/// refines on a stream of its own while the raycast runs, its passes that write the map waiting
/// for the raycast's end. Tracked on the device, each frame fused by the CPU at the device's pose,
/// refining after its raycast too: the same splits and merges and blocks per level within the
/// bounds of the tests above, and the model the last frame leaves (raycast before its splits and
/// merges; the frame count makes it a refining frame) as the CPU's. Two trackers would drift
/// apart by rounding (TracksAsTheCpuDoes), a split decided at its threshold tipping one way on one
/// and the other way on the other, and the two models' normals then differ over whole blocks.
TEST(GpuLoop, RefinesBesideTheRaycastAsTheCpuRefinesAfterIt) {
  HIVOX_REQUIRE_CUDA();
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=40&noise=kinect"));
  const CameraRig& rig = data.info().rig;
  ReconstructionParams p = params_for(3, 0.002f, 0.024f);
  p.refine_after_raycast = true;
  // The opt-in faulted on an H200 (docs/cuda.md): a device loop made with it says so, once.
  testing::internal::CaptureStderr();
  cuda::GpuReconstruction gpu(p, rig);
  const std::string warned = testing::internal::GetCapturedStderr();
  EXPECT_TRUE(test::contains(warned, "--refine-after-raycast") &&
              test::contains(warned, "not yet sound on a GPU"))
      << warned;
  p.device = Device::cpu();
  Reconstruction cpu(p, rig);
  const Pose first = *data.read(0).T_wc_gt;
  const std::size_t frames = frames_to_run(39, 17);  // the last (index 38 or 16) refines
  int64_t cpu_splits = 0, cpu_merges = 0, gpu_splits = 0, gpu_merges = 0;
  for (std::size_t i = 0; i < frames; ++i) {
    const RgbdFrame f = data.read(i);
    const FrameStats& g = gpu.track_and_integrate(f, first);
    ASSERT_TRUE(g.fused) << "frame " << i;
    const FrameStats& c = cpu.integrate(f, gpu.trajectory().back().T_wc);
    cpu_splits += c.splits;
    cpu_merges += c.merges;
    gpu_splits += g.splits;
    gpu_merges += g.merges;
  }
  const std::unique_ptr<VoxelBlockMap> downloaded = gpu.download_map();
  std::printf(
      "[ refine   ] after the raycast, %zu frames tracked on the device: splits %lld / %lld, "
      "merges %lld / %lld (CPU / GPU); blocks per level %s / %s; the last frame %lld splits, "
      "%lld merges\n",
      frames, static_cast<long long>(cpu_splits), static_cast<long long>(gpu_splits),
      static_cast<long long>(cpu_merges), static_cast<long long>(gpu_merges),
      fmt_levels(cpu.map()).c_str(), fmt_levels(*downloaded).c_str(),
      static_cast<long long>(gpu.frames().back().splits),
      static_cast<long long>(gpu.frames().back().merges));
  EXPECT_GT(gpu.frames().back().splits + gpu.frames().back().merges, 0);
  expect_same_refinement(cpu_splits, gpu_splits, cpu_merges, gpu_merges, cpu.map(), *downloaded);
  // The device's model shows the levels before the last frame's splits and merges, as the CPU's
  // does, not those after them (the map's now).
  const RaycastResult model = gpu.download_model();
  expect_same_raycast(cpu.last_raycast(), model);
  Raycaster raycaster(p.raycast);
  const RaycastResult& now =
      raycaster.raycast(cpu.map(), model.camera, model.T_wc, p.fusion.depth_range);
  const auto levels_apart = [&](const RaycastResult& x) {
    int64_t n = 0;
    for (int y = 0; y < model.depth_m.height(); ++y)
      for (int x0 = 0; x0 < model.depth_m.width(); ++x0)
        n += model.hit(x0, y) && x.hit(x0, y) && model.levels(x0, y) != x.levels(x0, y);
    return n;
  };
  const int64_t before = levels_apart(cpu.last_raycast()), after = levels_apart(now);
  std::printf(
      "[ refine   ] the model's levels: %lld pixels apart from the CPU's model, %lld from "
      "the map's after the edits\n",
      static_cast<long long>(before), static_cast<long long>(after));
  EXPECT_LT(3 * before, after);
}

/// Frames uploaded and their pyramids made beside the raycast (set_upload_beside_raycast): a
/// matter of scheduling, so the default's poses, iterations, map and model to the bit, tracked
/// with colour, refining before the raycast and after it (then three streams at once), and a
/// frame at a given pose last. Refining after the raycast, the refinement in order after it on
/// the loop's stream instead of beside it (set_refine_beside_raycast(false)) is scheduling too.
TEST(GpuLoop, UploadsBesideTheRaycastWithTheSameResults) {
  HIVOX_REQUIRE_CUDA();
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=40&noise=kinect"));
  const CameraRig& rig = data.info().rig;
  const Pose first = *data.read(0).T_wc_gt;
  const std::size_t frames = frames_to_run(30, 8);
  for (const bool refine_after : {false, true}) {
    SCOPED_TRACE(refine_after ? "refining after the raycast" : "refining before it");
    ReconstructionParams p = params_for(3, 0.002f, 0.024f);
    p.refine_after_raycast = refine_after;
    cuda::GpuReconstruction plain(p, rig), beside(p, rig);
    beside.set_upload_beside_raycast(true);
    std::vector<cuda::GpuReconstruction*> runs{&plain, &beside};
    std::unique_ptr<cuda::GpuReconstruction> in_order;
    if (refine_after) {
      in_order = std::make_unique<cuda::GpuReconstruction>(p, rig);
      in_order->set_refine_beside_raycast(false);
      runs.push_back(in_order.get());
    }
    // One run after the other: a run's waits for the device in between the other's frames
    // would end the other's raycast before its next upload, and hide the overlap.
    for (cuda::GpuReconstruction* gpu : runs) {
      for (std::size_t i = 0; i < frames; ++i) gpu->track_and_integrate(data.read(i), first);
      const RgbdFrame last = data.read(frames);
      gpu->integrate(last, *last.T_wc_gt);
    }
    const DeviceResult expected = device_result(plain, p);
    for (std::size_t r = 1; r < runs.size(); ++r) {
      SCOPED_TRACE(r == 1 ? "frames up beside the raycast" : "refinement in order after it");
      for (std::size_t i = 0; i < frames; ++i) {
        const FrameStats &a = plain.frames()[i], &b = runs[r]->frames()[i];
        EXPECT_TRUE(b.fused) << "frame " << i;
        EXPECT_EQ(a.valid_pixels, b.valid_pixels) << "frame " << i;
        EXPECT_EQ(a.track_iterations, b.track_iterations) << "frame " << i;
        EXPECT_EQ(a.splits, b.splits) << "frame " << i;
      }
      // The map, the model and the poses (the last frame fused at a given pose: in the
      // trajectory).
      expect_same_results(expected, device_result(*runs[r], p));
      EXPECT_GT(runs[r]->blocks_in_use(), 1000);
    }
  }
}

/// With the default capacities (2^20 pool blocks) the device holds no more memory for a map
/// than the CPU counts for the same map, on a fixed grid and in a hierarchy that merges: the
/// pool's voxels and metadata are committed up to its high-water mark, the CPU's metadata is
/// held whole.
TEST(GpuLoop, HoldsNoMoreMemoryForAMapThanTheCpu) {
  HIVOX_REQUIRE_CUDA();
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=30&noise=kinect"));
  const CameraRig& rig = data.info().rig;
  for (const int levels : {1, 3}) {
    ReconstructionParams p;
    p.map.levels = levels;
    p.device = Device::cuda();
    cuda::GpuReconstruction gpu(p, rig);
    p.device = Device::cpu();
    Reconstruction cpu(p, rig);
    int64_t merges = 0;
    for (std::size_t i = 0; i < data.size(); ++i) {
      const RgbdFrame f = data.read(i);
      cpu.integrate(f, *f.T_wc_gt);
      merges += gpu.integrate(f, *f.T_wc_gt).merges;
    }
    const int64_t device = gpu.map_memory_bytes(), host = cpu.map().memory_bytes();
    std::printf(
        "[ memory   ] %d level(s): the map holds %.1f MiB on the device, %.1f MiB on the CPU "
        "(%lld / %lld blocks, %lld merges on the device)\n",
        levels, device / 1048576.0, host / 1048576.0, static_cast<long long>(gpu.blocks_in_use()),
        static_cast<long long>(cpu.map().blocks_in_use()), static_cast<long long>(merges));
    ASSERT_GT(cpu.map().blocks_in_use(), 1000);
    if (levels > 1) {
      EXPECT_GT(merges, 0);
    }
    EXPECT_LE(device, host) << levels << " level(s)";
  }
}

/// Leaves `bytes` of the device's memory free while it lives: the emulation's device is made
/// smaller, a GPU's filled by one allocation.
class DeviceMemoryLeft {
 public:
  explicit DeviceMemoryLeft(std::size_t bytes) {
    std::size_t free = 0;
    cuda::check_status(cudaMemGetInfo(&free, &total_), "asking for the free memory");
#if defined(HIVOX_CUDA_EMULATION)
    hivoxEmulationSetDeviceMemory(total_ - free + bytes);
#else
    // What cudaMemGetInfo calls free may not all come in one allocation: a little less then.
    constexpr std::size_t kStep = std::size_t{16} << 20;
    for (std::size_t n = free > bytes ? free - bytes : 0; n > 0 && hog_ == nullptr;
         n = n > kStep ? n - kStep : 0) {
      if (cudaMalloc(&hog_, n) != cudaSuccess) {
        hog_ = nullptr;
        cudaGetLastError();
      }
    }
#endif
  }
  ~DeviceMemoryLeft() {
#if defined(HIVOX_CUDA_EMULATION)
    hivoxEmulationSetDeviceMemory(total_);
#else
    cudaFree(hog_);
#endif
  }
  DeviceMemoryLeft(const DeviceMemoryLeft&) = delete;
  DeviceMemoryLeft& operator=(const DeviceMemoryLeft&) = delete;

 private:
  std::size_t total_ = 0;
#if !defined(HIVOX_CUDA_EMULATION)
  void* hog_ = nullptr;
#endif
};

/// A device that fills while the map grows: the pool stops where the memory ends, new blocks
/// beyond it are dropped and counted, splits wait, and the run goes on (tracked frames, the map
/// and its mesh intact). With no memory left for the mesher or a render's images, the mesh and
/// the render are made on the host.
TEST(GpuLoop, ADeviceThatFillsDropsAndCountsBlocksAndGoesOn) {
  HIVOX_REQUIRE_CUDA();
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=30&noise=kinect"));
  constexpr std::size_t kFrames = 12;
  const CameraRig& rig = data.info().rig;
  const ReconstructionParams p = params_for(3, 0.002f, 0.024f);
  int64_t full_blocks = 0;
  double block_bytes = 0;
  {
    cuda::GpuReconstruction gpu(p, rig);
    for (std::size_t i = 0; i < kFrames; ++i)
      gpu.track_and_integrate(data.read(i), *data.read(0).T_wc_gt);
    full_blocks = gpu.blocks_in_use();
    block_bytes = static_cast<double>(gpu.map_memory_bytes()) / static_cast<double>(full_blocks);
  }
  cuda::GpuReconstruction gpu(p, rig);
  // Room for about half the blocks the map grows to (the pool's metadata and the tables apart).
  auto left = std::make_unique<DeviceMemoryLeft>(
      cuda::kPoolKeepsFreeBytes + static_cast<std::size_t>(0.3 * block_bytes * full_blocks));
  int64_t dropped = 0, waiting = 0;
  for (std::size_t i = 0; i < kFrames; ++i) {
    const FrameStats& s = gpu.track_and_integrate(data.read(i), *data.read(0).T_wc_gt);
    dropped += s.dropped_blocks;
    waiting += s.refine_waiting;
  }
  std::printf("[ full     ] %lld of %lld blocks, %lld dropped, %lld splits or merges waited\n",
              static_cast<long long>(gpu.blocks_in_use()), static_cast<long long>(full_blocks),
              static_cast<long long>(dropped), static_cast<long long>(waiting));
  EXPECT_GT(dropped, 0);
  EXPECT_EQ(gpu.dropped_blocks(), dropped);
  EXPECT_LT(gpu.blocks_in_use(), full_blocks);
  EXPECT_GT(gpu.blocks_in_use(), full_blocks / 10);
  // Every frame tracked, near the true trajectory still (the map holds the first frames' view).
  ASSERT_EQ(gpu.trajectory().size(), kFrames);
  for (std::size_t i = 0; i < kFrames; ++i)
    EXPECT_LT((gpu.trajectory()[i].T_wc.translation() - data.read(i).T_wc_gt->translation()).norm(),
              0.01)
        << "frame " << i;
  // The map comes back whole: every block in use, in the committed pool.
  const std::unique_ptr<VoxelBlockMap> map = gpu.download_map();
  EXPECT_EQ(map->blocks_in_use(), gpu.blocks_in_use());
  {
    SCOPED_TRACE("the device's map after it filled");
    test::expect_hierarchy_consistent(*map);
  }
  const TriangleMesh host = extract_mesh(*map);
  EXPECT_GT(host.triangles.size(), 1000u);
  {
    const DeviceMemoryLeft none(0);
    const TriangleMesh mesh = gpu.extract_mesh();  // on the host: the device has no room for it
    EXPECT_EQ(mesh.positions_w, host.positions_w);
    EXPECT_EQ(mesh.triangles, host.triangles);
    // A render likewise: the host's raycast of the map where the device has no room for its
    // images (the emulation's device is left exactly full: the CPU's raycast, to the bit). On a
    // GPU the memory taken leaves up to 16 MiB free, which the images may fit: then it is the
    // device's render, the CPU's raycast within the device render's tolerance (H200, 9c82ac7:
    // not to the bit).
    const Pose& T_wc = gpu.trajectory().back().T_wc;
    const RaycastResult render = gpu.render(rig.depth_camera, T_wc, p.fusion.depth_range);
    Raycaster raycaster(p.raycast);
    const RaycastResult& cpu =
        raycaster.raycast(*map, rig.depth_camera, T_wc, p.fusion.depth_range);
#if defined(HIVOX_CUDA_EMULATION)
    EXPECT_TRUE(same_depths(cpu, render));
#else
    expect_same_raycast(cpu, render);
#endif
    EXPECT_GT(hit_count(render), static_cast<int64_t>(render.depth_m.size() / 10));
  }
  // With the memory back, the map grows again.
  left.reset();
  const int64_t before = gpu.blocks_in_use();
  const RgbdFrame later = data.read(29);
  gpu.integrate(later, *later.T_wc_gt);
  EXPECT_GT(gpu.blocks_in_use(), before);
}

/// Bytes the device has copied to the host so far: counted by the CPU emulation of CUDA; -1 on a
/// GPU (not counted there).
int64_t bytes_to_host() {
#if defined(HIVOX_CUDA_EMULATION)
  return static_cast<int64_t>(hivoxEmulationBytesToHost());
#else
  return -1;
#endif
}

/// GpuReconstruction::extract_mesh against extract_mesh on the downloaded map: the same vertices
/// (neither mesher fuses multiply-adds) and the same triangles, with each set of mesh parameters,
/// and with few mesher threads.
TEST(GpuLoop, MeshesOnTheDeviceAsTheCpuDoes) {
  HIVOX_REQUIRE_CUDA();
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=30&noise=kinect"));
  const ReconstructionParams p = params_for(3, 0.002f, 0.024f);
  cuda::GpuReconstruction gpu(p, data.info().rig);
  for (std::size_t i = 0; i < data.size(); ++i) {
    const RgbdFrame f = data.read(i);
    gpu.integrate(f, *f.T_wc_gt);
  }
  const std::unique_ptr<VoxelBlockMap> map = gpu.download_map();
  for (const int64_t n : map->blocks_per_level()) ASSERT_GT(n, 100) << fmt_levels(*map);
  {
    SCOPED_TRACE("the device's map");
    test::expect_hierarchy_consistent(*map);
  }
  // The device's mesh against the host's mesh of the downloaded map, vertex for vertex.
  const auto expect_same_mesh = [&](const TriangleMesh& a, const RemovedPieces& a_removed,
                                    const TriangleMesh& b, const RemovedPieces& b_removed) {
    ASSERT_GT(a.triangle_count(), 10000);
    ASSERT_EQ(a.vertex_count(), b.vertex_count());
    ASSERT_EQ(a.triangle_count(), b.triangle_count());
    ASSERT_EQ(a.normals_w.size(), b.normals_w.size());
    ASSERT_EQ(a.colors.size(), b.colors.size());
    EXPECT_EQ(a_removed.pieces, b_removed.pieces);
    const test::MeshDifferences d = test::mesh_differences(a, b);
    EXPECT_EQ(d.positions, 0) << test::describe_mesh_difference(a, b)
                              << test::describe_first_difference_in_map(a, b, *map);
    EXPECT_EQ(d.normals, 0);
    EXPECT_EQ(d.colors, 0);
    EXPECT_EQ(d.levels, 0);
    EXPECT_EQ(d.triangles, 0);
  };
  auto cases = test::mesh_param_cases();
  cases.emplace_back("bounds", MeshParams{});
  cases.back().second.bounds = Box3f{{0.4f, -0.5f, 0.5f}, {1.2f, 0.5f, 1.5f}};  // ~3 % of it
  TriangleMesh host_defaults;  // the host's mesh with the default parameters
  RemovedPieces host_defaults_removed;
  int64_t defaults_bytes = 0;  // what the device's mesh with them brought to the host
  for (const auto& [name, params] : cases) {
    SCOPED_TRACE(name);
    Stopwatch cpu_timer;
    RemovedPieces cpu_removed, gpu_removed;
    const TriangleMesh a = extract_mesh(*map, params, &cpu_removed);
    const double cpu_ms = cpu_timer.elapsed_ms();
    Stopwatch gpu_timer;
    const int64_t before = bytes_to_host();
    const TriangleMesh b = gpu.extract_mesh(params, &gpu_removed);
    const double gpu_ms = gpu_timer.elapsed_ms();
    if (std::string_view(name) == "defaults") {
      host_defaults = a;
      host_defaults_removed = cpu_removed;
      defaults_bytes = bytes_to_host() - before;
    }
    std::printf(
        "[ mesh     ] %s: %lld / %lld vertices, %lld / %lld triangles (CPU / GPU), "
        "%.1f / %.1f ms\n",
        name, static_cast<long long>(a.vertex_count()), static_cast<long long>(b.vertex_count()),
        static_cast<long long>(a.triangle_count()), static_cast<long long>(b.triangle_count()),
        cpu_ms, gpu_ms);
    expect_same_mesh(a, cpu_removed, b, gpu_removed);
  }
  {
    // With little device memory free the mesher has fewer threads (its scratch takes at most a
    // quarter of what is free: ~2600 threads here against one a block), each meshing several
    // blocks in turn with its scratch and look-up cache reused: the same mesh, made on the device
    // (only the mesh crosses the bus, not the map). On an H200 a tracked map's device mesh once
    // differed from the host's by a vertex, and under compute-sanitizer, which takes device
    // memory of its own, this test's meshes did: a mesh that moved with the thread count fails
    // here.
    SCOPED_TRACE("few mesher threads");
    ASSERT_FALSE(host_defaults.empty());
    RemovedPieces removed;
    const int64_t before = bytes_to_host();
    TriangleMesh mesh;
    {
      const DeviceMemoryLeft left(std::size_t{256} << 20);
      mesh = gpu.extract_mesh(MeshParams{}, &removed);
    }
    // Emulated, the bytes that crossed are counted: the same as with every thread, no map.
    if (before >= 0) {
      EXPECT_EQ(bytes_to_host() - before, defaults_bytes) << "meshed on the host instead";
    }
    expect_same_mesh(host_defaults, host_defaults_removed, mesh, removed);
  }
  // An empty map gives an empty mesh.
  cuda::GpuReconstruction empty(p, data.info().rig);
  EXPECT_TRUE(empty.extract_mesh().empty());
}

/// What a raycast's images take on the host, `pixels` of each.
int64_t raycast_bytes(int64_t pixels) {
  return pixels * static_cast<int64_t>(sizeof(float) + 2 * sizeof(Vec3f) + sizeof(Rgb8) + 1);
}

/// Renders on the device: the CPU's raycast of the same map (every ray marching, no hints) from
/// the last frame's pose and from a pose pulled back with another camera; only the images cross
/// the bus, and the frame's own raycast stays as it was.
TEST(GpuLoop, RendersOnTheDeviceAsTheCpuDoes) {
  HIVOX_REQUIRE_CUDA();
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=30&noise=kinect"));
  const CameraRig& rig = data.info().rig;
  const ReconstructionParams p = params_for(3, 0.002f, 0.024f);
  cuda::GpuReconstruction gpu(p, rig);
  // The model's raycast as two kernels, its marches split; a render, where every ray marches,
  // takes the one kernel and whole marches whatever the camera's size (the second view's is the
  // model's). Split, that view's render fails here (checked).
  gpu.set_queued_marches(true);
  gpu.set_split_marches(32);
  Pose last = Pose::Identity();
  for (std::size_t i = 0; i < frames_to_run(30, 10); ++i) {
    const RgbdFrame f = data.read(i);
    gpu.integrate(f, *f.T_wc_gt);
    last = *f.T_wc_gt;
  }
  const RaycastResult model = gpu.download_model();
  const std::unique_ptr<VoxelBlockMap> map = gpu.download_map();
  Raycaster raycaster(p.raycast);
  // Pulled back 0.6 m and raised 0.2 m (image up is -y), with a camera of half the size.
  Pose back = last;
  back.translate(Eigen::Vector3d(0.0, -0.2, -0.6));
  DepthRange far = p.fusion.depth_range;
  far.max_m = 4.0f;
  const std::array views{
      std::tuple{"the last frame's pose", rig.depth_camera, last, p.fusion.depth_range},
      std::tuple{"pulled back", rig.depth_camera.scaled(0.5f), back, far}};
  for (const auto& [name, camera, T_wc, range] : views) {
    SCOPED_TRACE(name);
    const int64_t before = bytes_to_host();
    const RaycastResult render = gpu.render(camera, T_wc, range);
    const int64_t pixels = static_cast<int64_t>(camera.width) * camera.height;
    if (before >= 0) {
      // The images, not the map (the map itself is larger than several renders).
      EXPECT_LE(bytes_to_host() - before, raycast_bytes(pixels) + 4096);
      EXPECT_GT(static_cast<int64_t>(map->memory_bytes()), 4 * raycast_bytes(pixels));
    }
    ASSERT_EQ(render.camera.width, camera.width);
    EXPECT_TRUE(render.T_wc.isApprox(T_wc));
    EXPECT_EQ(render.has_color, p.map.store_color);
    const RaycastResult& cpu = raycaster.raycast(*map, camera, T_wc, range);
    expect_same_raycast(cpu, render);
    // The levels hit and the colours there, pixel for pixel (where both hit at the same depth).
    int64_t same_depth = 0, level_differs = 0, color_differs = 0;
    for (int y = 0; y < camera.height; ++y) {
      for (int x = 0; x < camera.width; ++x) {
        if (!cpu.hit(x, y) || !render.hit(x, y) ||
            std::abs(cpu.depth_m(x, y) - render.depth_m(x, y)) > 1e-4f)
          continue;
        ++same_depth;
        level_differs += cpu.levels(x, y) != render.levels(x, y);
        const Rgb8 a = cpu.colors(x, y), b = render.colors(x, y);
        color_differs +=
            std::abs(a.r - b.r) > 1 || std::abs(a.g - b.g) > 1 || std::abs(a.b - b.b) > 1;
      }
    }
    std::printf(
        "[ render   ] %s: %dx%d, %lld pixels at the same depth, %lld levels and %lld "
        "colours differ there\n",
        name, camera.width, camera.height, static_cast<long long>(same_depth),
        static_cast<long long>(level_differs), static_cast<long long>(color_differs));
    EXPECT_GT(same_depth, pixels / 10);
    EXPECT_LE(level_differs, same_depth / 1000);
    EXPECT_LE(color_differs, same_depth / 1000);
  }
  // The frame's raycast (the next frame tracks against it) is as it was.
  EXPECT_TRUE(same_depths(model, gpu.download_model()));
  // Bad input: one line naming it.
  PinholeCamera bad = rig.depth_camera;
  bad.fx = -1.0f;
  EXPECT_THROW(gpu.render(bad, last, p.fusion.depth_range), Error);
  EXPECT_THROW(gpu.render(rig.depth_camera, last, DepthRange{2.0f, 1.0f}), Error);
}

/// `hivox render` and `hivox mesh` with `--device cuda` on a saved map: the map goes to the
/// device once and the views and the mesh are made there, as on the CPU; a missing device is
/// refused with one line naming it.
TEST(GpuLoop, TheMapCommandsRenderAndMeshOnTheDevice) {
  HIVOX_REQUIRE_CUDA();
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=30&noise=kinect"));
  ReconstructionParams p = params_for(3, 0.002f, 0.024f);
  p.device = Device::cpu();
  Reconstruction cpu(p, data.info().rig);
  const std::size_t frames = frames_to_run(12, 6);
  for (std::size_t i = 0; i < frames; ++i) {
    const RgbdFrame f = data.read(i);
    cpu.integrate(f, *f.T_wc_gt);
  }
  TempDir dir;
  const std::filesystem::path map = dir.path() / "desk.hvx";
  write_map_file(map, cpu.map(), p.fusion, cpu.session());
  const std::string pose =
      fmt::format("{:.6f}", fmt::join(to_tum(cpu.trajectory().back().T_wc), " "));
  for (const char* device : {"cpu", "cuda"}) {
    SCOPED_TRACE(device);
    const CliRun render =
        run_hivox(fmt::format("render {} --pose '{}' --out {} --device {}", map.string(), pose,
                              (dir.path() / device).string(), device));
    EXPECT_EQ(render.exit_code, 0) << render.output;
    const CliRun mesh = run_hivox(fmt::format("mesh {} --out {} --device {} --quiet", map.string(),
                                              (dir.path() / device / "mesh.ply").string(), device));
    EXPECT_EQ(mesh.exit_code, 0) << mesh.output;
    if (std::string_view(device) == "cuda") {
      EXPECT_NE(render.output.find("on cuda:0"), std::string::npos) << render.output;
    }
  }
  // The same pictures (shaded and levels; a pixel may differ where a ray grazes a surface) and
  // the same mesh.
  for (const char* picture : {"shaded.png", "levels.png"}) {
    const ColorImage a = read_color(dir.path() / "cpu" / picture);
    const ColorImage b = read_color(dir.path() / "cuda" / picture);
    ASSERT_EQ(a.width(), b.width());
    ASSERT_EQ(a.height(), b.height());
    int64_t differ = 0, lit = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
      const Rgb8 x = a.data()[i], y = b.data()[i];
      lit += x.r + x.g + x.b > 0;
      differ += std::abs(x.r - y.r) > 20 || std::abs(x.g - y.g) > 20 || std::abs(x.b - y.b) > 20;
    }
    std::printf("[ cli      ] %s: %lld of %lld lit pixels differ\n", picture,
                static_cast<long long>(differ), static_cast<long long>(lit));
    EXPECT_GT(lit, static_cast<int64_t>(a.size()) / 2) << picture;
    EXPECT_LE(differ, lit / 200) << picture;
  }
  const TriangleMesh a = read_ply(dir.path() / "cpu" / "mesh.ply");
  const TriangleMesh b = read_ply(dir.path() / "cuda" / "mesh.ply");
  ASSERT_GT(a.triangle_count(), 10000);
  EXPECT_NEAR(static_cast<double>(b.triangle_count()), static_cast<double>(a.triangle_count()),
              0.001 * static_cast<double>(a.triangle_count()));
  // A device that is not there: one line naming it and what there is, before the map is read;
  // no files.
  const CliRun missing = run_hivox(fmt::format("mesh {} --out {} --device cuda:63 --quiet",
                                               map.string(), (dir.path() / "none.ply").string()));
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.output.find("device cuda:63: no such CUDA device here ("), std::string::npos)
      << missing.output;
  EXPECT_NE(missing.output.find(" found: cuda:0"), std::string::npos) << missing.output;
  EXPECT_EQ(missing.output.find("loaded"), std::string::npos) << missing.output;
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "none.ply"));
}

/// The CLI's and the bindings' way onto the GPU: a Reconstruction on `cuda` (its frames on the
/// device, its map the host's copy) and a whole run with its result files.
TEST(GpuLoop, AReconstructionAndARunOnTheDevice) {
  HIVOX_REQUIRE_CUDA();
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=30&noise=kinect"));
  const CameraRig& rig = data.info().rig;
  ReconstructionParams p = params_for(3, 0.002f, 0.024f);
  const std::unique_ptr<Reconstruction> gpu = make_reconstruction(p, rig);
  p.device = Device::cpu();
  Reconstruction cpu(p, rig);
  const Pose first = *data.read(0).T_wc_gt;
  for (std::size_t i = 0; i < frames_to_run(data.size(), 20); ++i) {
    const RgbdFrame f = data.read(i);
    cpu.track_and_integrate(f, 0.0, first);
    const FrameStats& s = gpu->track_and_integrate(f, 0.0, first);
    EXPECT_TRUE(s.fused) << "frame " << i;
    EXPECT_EQ(s.blocks_total, gpu->map().blocks_in_use()) << "frame " << i;
  }
  const FrameStats& last = gpu->frame_stats().back();
  EXPECT_GT(last.raycast_hits, 50000);
  EXPECT_GT(last.track_iterations, 0);
  EXPECT_EQ(gpu->tracking_counts().lost, 0);
  const Pose d = cpu.trajectory().back().T_wc.inverse() * gpu->trajectory().back().T_wc;
  EXPECT_LT(d.translation().norm(), 1e-3);
  for (int l = 0; l < 3; ++l)
    EXPECT_NEAR(static_cast<double>(gpu->map().blocks_per_level()[l]),
                static_cast<double>(cpu.map().blocks_per_level()[l]),
                10.0 + 0.02 * cpu.map().blocks_per_level()[l])
        << "level " << l;
  EXPECT_GT(gpu->last_raycast().depth_m.width(), 0);
  {
    SCOPED_TRACE("the device's tracked map");
    test::expect_hierarchy_consistent(gpu->map());
  }
  // The Reconstruction meshes on the device: the mesh of its map downloaded, vertex for vertex.
  // And the same mesh when made again (a result that moves between calls would be a race or a
  // read of memory nothing wrote, not arithmetic).
  const TriangleMesh on_device = gpu->extract_mesh();
  const TriangleMesh on_host = extract_mesh(gpu->map());
  {
    const TriangleMesh again = gpu->extract_mesh();
    const test::MeshDifferences d = test::mesh_differences(on_device, again);
    std::printf("[ mesh     ] the device's mesh made twice: %lld / %lld vertices, %lld apart\n",
                static_cast<long long>(on_device.vertex_count()),
                static_cast<long long>(again.vertex_count()), static_cast<long long>(d.positions));
    EXPECT_EQ(again.vertex_count(), on_device.vertex_count());
    EXPECT_EQ(d.positions, 0) << test::describe_mesh_difference(on_device, again);
    EXPECT_EQ(again.triangles, on_device.triangles);
  }
  ASSERT_EQ(on_device.vertex_count(), on_host.vertex_count())
      << test::describe_mesh_difference(on_device, on_host)
      << test::describe_first_difference_in_map(on_device, on_host, gpu->map());
  EXPECT_EQ(on_device.triangle_count(), on_host.triangle_count());
  EXPECT_LT(test::mesh_differences(on_device, on_host).farthest_m, 1e-6f)
      << test::describe_mesh_difference(on_device, on_host)
      << test::describe_first_difference_in_map(on_device, on_host, gpu->map());

  {
    // A render after a frame the host's copy of the map has not seen (the last fused again): made
    // on the device, only the images cross the bus; the CPU's raycast of the map gives it.
    SCOPED_TRACE("render");
    const Pose T_wc = gpu->trajectory().back().T_wc;
    gpu->integrate(data.read(frames_to_run(data.size(), 20) - 1), T_wc);  // fused once more
    const int64_t before = bytes_to_host();
    const RaycastResult render = gpu->render(rig.depth_camera, T_wc);
    if (before >= 0) {
      EXPECT_LE(bytes_to_host() - before,
                raycast_bytes(static_cast<int64_t>(render.depth_m.size())) + 4096);
    }
    EXPECT_GT(hit_count(render), 200000);
    Raycaster raycaster(p.raycast);
    expect_same_raycast(raycaster.raycast(gpu->map(), rig.depth_camera, T_wc, p.fusion.depth_range),
                        render);
  }

  // A whole run, as `hivox reconstruct --device cuda` makes it (meshed on the device).
  TempDir dir;
  RunParams run;
  run.reconstruction = params_for(3, 0.002f, 0.024f);
  run.out_dir = dir.path() / "out";
  run.max_frames = frames_to_run(20, 8);
  SyntheticDataset reader(parse_synthetic_spec("synthetic:desk?frames=20&noise=kinect"));
  const RunResult r = run_reconstruction(reader, run);
  EXPECT_EQ(r.summary.frames_fused, run.max_frames);
  ASSERT_TRUE(r.summary.ate.has_value());
  EXPECT_LT(r.summary.ate->rmse_m, 0.01);
  EXPECT_TRUE(std::filesystem::exists(run.out_dir / "mesh.ply"));
  // stats.json names the GPU the run ran on.
  const nlohmann::json stats = nlohmann::json::parse(read_whole_file(run.out_dir / "stats.json"));
  EXPECT_EQ(stats.at("gpu").at("device"), "cuda:0");
  EXPECT_EQ(stats.at("gpu").at("name"), device);
  EXPECT_GT(stats.at("gpu").at("memory_bytes").get<int64_t>(), 0);
  std::printf("[ run      ] %zu frames on the device: ATE %.2f mm, %lld mesh triangles\n",
              run.max_frames, 1e3 * r.summary.ate->rmse_m,
              static_cast<long long>(r.summary.mesh_triangles));
  EXPECT_GT(r.summary.mesh_triangles, 10000);
}

// What `hivox devices` and Python's hivox.devices() list: the CPU, then this device, described.
TEST(GpuLoop, DevicesListTheGpu) {
  HIVOX_REQUIRE_CUDA();
  const DeviceList list = list_devices();
  EXPECT_TRUE(list.cuda_built);
  EXPECT_TRUE(list.cuda_note.empty()) << list.cuda_note;
  ASSERT_GE(list.devices.size(), 2u);
  EXPECT_TRUE(list.devices[0].device.is_cpu());
  const DeviceInfo& gpu = list.devices[1];
  EXPECT_EQ(gpu.device, Device::cuda(0));
  EXPECT_EQ(gpu.name, device);
  EXPECT_GT(gpu.free_bytes, 0);
  EXPECT_LE(gpu.free_bytes, gpu.memory_bytes);
  EXPECT_GE(gpu.compute_major, 3);
  EXPECT_GT(gpu.multiprocessors, 0);
  std::printf("[ devices  ] %s: %.1f of %.1f GiB free, compute %d.%d, %d multiprocessors\n",
              gpu.name.c_str(), gpu.free_bytes / 1073741824.0, gpu.memory_bytes / 1073741824.0,
              gpu.compute_major, gpu.compute_minor, gpu.multiprocessors);
}

TEST(GpuLoop, BadInputIsRefusedWithAClearError) {
  HIVOX_REQUIRE_CUDA();
  SyntheticDataset data(parse_synthetic_spec("synthetic:desk?frames=2"));
  ReconstructionParams p = params_for(1, 0.005f, 0.02f);
  cuda::GpuReconstruction gpu(p, data.info().rig);
  RgbdFrame f = data.read(0);
  f.depth_m.resize(f.depth_m.width() / 2, f.depth_m.height() / 2);
  const Error size = error_of([&] { gpu.integrate(f, Pose::Identity()); });
  EXPECT_EQ(size.code(), ErrorCode::InvalidArgument);
  EXPECT_TRUE(contains(size.what(), "depth image is 320x240")) << size.what();
  // Register caps the ray kernel is not built with; split marches beyond a warp.
  for (const int bad : {-1, 1, 100, 256}) {
    const Error cap = error_of([&] { gpu.set_raycast_registers(bad); });
    EXPECT_EQ(cap.code(), ErrorCode::InvalidArgument);
    EXPECT_TRUE(contains(cap.what(), fmt::format("raycast registers: at most {} ", bad)))
        << cap.what();
  }
  EXPECT_EQ(error_of([&] { gpu.set_split_marches(33); }).code(), ErrorCode::InvalidArgument);
  for (const int bad : {0, 3, 8}) {
    const Error pixels = error_of([&] { gpu.set_allocation_pixels(bad); });
    EXPECT_EQ(pixels.code(), ErrorCode::InvalidArgument);
    EXPECT_TRUE(contains(pixels.what(), fmt::format("allocation: {} pixels a thread", bad)))
        << pixels.what();
  }
  p.device = Device::cpu();
  const Error cpu = error_of([&] { cuda::GpuReconstruction(p, data.info().rig); });
  EXPECT_TRUE(contains(cpu.what(), "needs a CUDA device")) << cpu.what();
  p.device = Device::cuda(99);
  const Error missing = error_of([&] { cuda::GpuReconstruction(p, data.info().rig); });
  EXPECT_EQ(missing.code(), ErrorCode::Unsupported);
  EXPECT_TRUE(contains(missing.what(), "cuda:99")) << missing.what();
}

}  // namespace
}  // namespace hivox::test

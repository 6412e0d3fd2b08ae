// Per-stage benchmarks on a fixed workload: the first frames of TUM fr1/rpy (ground-truth poses)
// when ../shared/data is present, else the synthetic desk. The map is first filled with
// `kWarmupFrames` frames; each benchmark then repeats one stage on the next frame (the raycasts
// after fusing it, as the pipeline does).
//
// Workload knobs (environment): HIVOX_BENCH_VOXEL (m, default 0.005), HIVOX_BENCH_TRUNC (m,
// default 0.02), HIVOX_BENCH_LEVELS (default 1; with more, the warm-up refines every frame as
// the pipeline does), HIVOX_BENCH_WARMUP (frames, default 100).

#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "core/parallel.h"
#include "hivox/core/timer.h"
#include "hivox/fusion/integrator.h"
#include "hivox/io/dataset.h"
#include "hivox/io/intrinsics_io.h"
#include "hivox/io/mesh_file.h"
#include "hivox/io/read_ahead.h"
#include "hivox/io/trajectory_io.h"
#include "hivox/map/voxel_block_map.h"
#include "hivox/mesh/extract_mesh.h"
#include "hivox/raycast/hints.h"
#include "hivox/raycast/raycaster.h"
#include "hivox/refine/refiner.h"
#include "hivox/synth_mesh/mesh_render.h"
#include "hivox/track/tracker.h"
#include "synth_mesh/mesh_render_modes.h"

namespace hivox {
namespace {

double env_or(const char* name, double fallback) {
  const char* v = std::getenv(name);
  return v ? std::atof(v) : fallback;
}

/// The benchmarks' dataset: TUM fr1/rpy when ../shared/data holds it, else the synthetic desk.
std::string bench_dataset() {
  const std::filesystem::path tum = std::filesystem::path(HIVOX_BENCH_DATA_DIR) / "tum_fr1_rpy";
  return std::filesystem::is_directory(tum) ? tum.string() : "synthetic:desk?frames=200";
}

struct Workload {
  std::unique_ptr<DatasetReader> reader;
  std::unique_ptr<VoxelBlockMap> map;
  FusionParams fusion;
  RgbdFrame frame;                        // the frame each benchmark processes
  Pose previous_T_wc = Pose::Identity();  // the pose of the frame before it
  FusionInput input;
  std::string name;
  bool frame_fused = false;

  Workload() {
    name = bench_dataset();
    reader = open_dataset(name);
    MapParams mp;
    mp.voxel_size_m = static_cast<float>(env_or("HIVOX_BENCH_VOXEL", 0.005));
    mp.levels = static_cast<int>(env_or("HIVOX_BENCH_LEVELS", 1));
    mp.truncation_m = static_cast<float>(env_or("HIVOX_BENCH_TRUNC", 0.02));
    map = std::make_unique<VoxelBlockMap>(mp);
    TsdfIntegrator integrator(fusion);
    Refiner refiner;  // with several levels, blocks split and merge as in the pipeline
    const auto warmup = static_cast<std::size_t>(env_or("HIVOX_BENCH_WARMUP", 100));
    for (std::size_t i = 0; i < warmup && i + 1 < reader->size(); ++i) {
      const RgbdFrame f = reader->read(i);
      if (!f.T_wc_gt) continue;
      const FusionInput in = make_input(f);
      previous_T_wc = in.T_wc;
      const Allocation a = integrator.fuse(*map, in);
      if (mp.levels > 1) refiner.refine(*map, a.visible_blocks, in.T_wc);
    }
    frame = reader->read(warmup);
    input = make_input(frame);
  }

  /// Fuses `frame` into the map unless a benchmark did already (the raycasts then see the map
  /// the pipeline raycasts, and their depth hint is the depth just fused).
  void fuse_frame_once() {
    if (frame_fused) return;
    TsdfIntegrator integrator(fusion);
    integrator.fuse(*map, input);
    frame_fused = true;
  }

  FusionInput make_input(const RgbdFrame& f) const {
    return fusion_input(reader->info().rig, f, f.T_wc_gt.value_or(Pose::Identity()));
  }
  const PinholeCamera& camera() const { return input.rig.depth_camera; }
  const DepthRange& range() const { return fusion.depth_range; }
};

Workload& workload() {
  static Workload w;
  return w;
}

void BM_Allocate(benchmark::State& state) {
  Workload& w = workload();
  TsdfIntegrator integrator(w.fusion);
  Allocation a;
  for (auto _ : state) a = integrator.allocate(*w.map, w.input);
  state.counters["visible_blocks"] = static_cast<double>(a.visible_blocks.size());
  state.SetLabel(w.name);
}

/// Argument: the depth sampling (0 nearest pixel, 1 bilinear).
void BM_Integrate(benchmark::State& state) {
  Workload& w = workload();
  FusionParams fp = w.fusion;
  fp.depth_sampling = state.range(0) == 0 ? DepthSampling::Nearest : DepthSampling::Bilinear;
  TsdfIntegrator integrator(fp);
  const Allocation a = integrator.allocate(*w.map, w.input);
  for (auto _ : state) integrator.integrate(*w.map, w.input, a.visible_blocks);
  w.frame_fused = true;
  state.counters["visible_blocks"] = static_cast<double>(a.visible_blocks.size());
  state.SetLabel(std::string(to_string(fp.depth_sampling)));
}

enum class HintKind { None, Depth, DepthAndWarped };

void raycast(benchmark::State& state, HintKind kind) {
  Workload& w = workload();
  w.fuse_frame_once();  // as in the pipeline: the frame is fused, then raycast
  Raycaster raycaster;
  // As in the pipeline: the depth just fused, and where the frame has no depth or the search at
  // it fails, the previous frame's raycast warped into this view.
  Raycaster previous;
  if (kind == HintKind::DepthAndWarped)
    previous.raycast(*w.map, w.camera(), w.previous_T_wc, w.range());
  FrameHints builder;
  RaycastHints hints;
  if (kind != HintKind::None)
    hints = builder.build(w.frame.depth_m, w.camera(), 1, w.input.T_wc,
                          kind == HintKind::DepthAndWarped ? &previous.result() : nullptr,
                          w.map->params().truncation_m);
  RaycastStats s;
  for (auto _ : state) raycaster.raycast(*w.map, w.camera(), w.input.T_wc, w.range(), hints, &s);
  state.counters["hits"] = static_cast<double>(s.hits);
  state.counters["at_hint"] = static_cast<double>(s.found_at_hint);
  state.counters["at_fallback"] = static_cast<double>(s.found_at_fallback);
  state.counters["blocks"] = static_cast<double>(w.map->blocks_in_use());
}
void BM_Raycast(benchmark::State& state) {
  raycast(state, HintKind::None);
}
void BM_RaycastHinted(benchmark::State& state) {
  raycast(state, HintKind::Depth);
}
/// The pipeline's raycast: hints from the depth just fused and the previous raycast, warped.
void BM_RaycastPipeline(benchmark::State& state) {
  raycast(state, HintKind::DepthAndWarped);
}

/// The previous frame's raycast warped into this view (the pipeline's fallback hints).
void BM_WarpRaycast(benchmark::State& state) {
  Workload& w = workload();
  Raycaster previous;
  previous.raycast(*w.map, w.camera(), w.previous_T_wc, w.range());
  DepthImage warped;
  WarpScratch scratch;  // as the pipeline keeps it
  for (auto _ : state)
    warp_raycast_depth(previous.result(), w.camera(), w.input.T_wc, w.map->params().truncation_m,
                       &warped, &scratch);
  int64_t covered = 0;
  for (std::size_t i = 0; i < warped.size(); ++i) covered += warped.data()[i] > 0.0f;
  state.counters["covered"] = static_cast<double>(covered);
}

/// Tracking the frame against the model raycast from the previous frame's pose at the pipeline's
/// resolution (TrackParams::model_subsample), starting from that pose.
void BM_Track(benchmark::State& state) {
  Workload& w = workload();
  const TrackParams tp;
  Raycaster model;
  model.raycast(*w.map, w.camera().subsampled(tp.model_subsample), w.previous_T_wc, w.range());
  Tracker tracker(tp, w.range());
  TrackResult r;
  for (auto _ : state)
    r = tracker.track(*w.input.depth_m, w.camera(), model.result(), w.previous_T_wc);
  state.counters["iterations"] = r.iterations;
  state.counters["inlier_ratio"] = r.inlier_ratio;
  state.counters["icp_ms"] = r.icp_ms;
}

void BM_ExtractMesh(benchmark::State& state) {
  Workload& w = workload();
  TriangleMesh mesh;
  for (auto _ : state) mesh = extract_mesh(*w.map);
  state.counters["triangles"] = static_cast<double>(mesh.triangle_count());
}

/// Rendering a mesh (`hivox synth --mesh`): Replica office0's 50k-triangle mesh at its 1200x680
/// camera, cycling through the first 100 poses of its trajectory. Skipped without the data.
/// Argument: 0 ray packets (`render`), 1 one ray per pixel.
void BM_MeshRender(benchmark::State& state) {
  const std::filesystem::path dir = std::filesystem::path(HIVOX_BENCH_DATA_DIR) / "replica_office0";
  if (!std::filesystem::is_directory(dir)) {
    state.SkipWithError("../shared/data/replica_office0 not found");
    return;
  }
  static const MeshScene scene(read_mesh(dir / "office0_mesh_decimated50k.ply"));
  static const std::vector<StampedPose> poses = read_tum_trajectory(dir / "groundtruth.txt");
  static const PinholeCamera camera = read_intrinsics_json(dir / "intrinsics.json").camera;
  const MeshRayMode mode = state.range(0) == 0 ? MeshRayMode::Packets : MeshRayMode::Single;
  std::size_t i = 0, hits = 0;
  for (auto _ : state) {
    const RenderedFrame f = render_mesh(scene, camera, poses[i++ % 100].T_wc, 10.0, mode);
    benchmark::DoNotOptimize(f.depth_m.data());
    hits = 0;
    for (std::size_t k = 0; k < f.depth_m.size(); ++k) hits += f.depth_m.data()[k] > 0.0f;
  }
  state.counters["hits"] = static_cast<double>(hits);
  state.SetLabel(mode == MeshRayMode::Packets ? "4x4 packets" : "ray by ray");
}

/// Reading frames as a run does (PNG decoding, lens distortion), 32 a repetition. Argument: the
/// reading threads (0: each frame in turn on this thread; n: ReadAhead on n threads, 2n frames
/// ahead). The same dataset as the workload, without its fused map.
void BM_ReadFrames(benchmark::State& state) {
  const std::string name = bench_dataset();
  const std::unique_ptr<DatasetReader> reader = open_dataset(name);
  const auto threads = static_cast<int>(state.range(0));
  constexpr std::size_t kFrames = 32;
  std::size_t first = 0;
  for (auto _ : state) {
    ReadAhead frames(*reader, first, first + kFrames, ReadAhead::frames_for(threads), threads);
    for (std::size_t i = 0; i < kFrames; ++i)
      benchmark::DoNotOptimize(frames.next().depth_m.data());
    first = (first + kFrames) % (reader->size() - kFrames);
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * kFrames));
  state.SetLabel(name);
}

/// Reading ahead beside a loop whose own work a frame is a short parallel copy (1.5 MB, a frame's
/// upload) and a 2.5 ms wait (the device's frame): a GPU run's host side. Argument: the reading
/// threads (0: in turn). Counter `copy_ms`: the copy's time a frame, which grows many times over
/// where the readers and the copy's threads ask for more cores than there are.
void BM_ReadAheadBesideALoop(benchmark::State& state) {
  const std::unique_ptr<DatasetReader> reader = open_dataset(bench_dataset());
  const auto threads = static_cast<int>(state.range(0));
  constexpr std::size_t kFrames = 32;
  constexpr int64_t kParts = 64, kPartBytes = 24000;
  std::vector<char> from(kParts * kPartBytes, 1), to(from.size());
  std::size_t first = 0;
  double copy_ms = 0.0;
  for (auto _ : state) {
    ReadAhead frames(*reader, first, first + kFrames, ReadAhead::frames_for(threads), threads);
    for (std::size_t i = 0; i < kFrames; ++i) {
      benchmark::DoNotOptimize(frames.next().depth_m.data());
      Stopwatch copy;
      parallel_for(Device::cpu(), kParts, [&](int64_t p) {
        std::memcpy(to.data() + p * kPartBytes, from.data() + p * kPartBytes, kPartBytes);
      });
      copy_ms += copy.elapsed_ms();
      std::this_thread::sleep_for(std::chrono::microseconds(2500));
    }
    first = (first + kFrames) % (reader->size() - kFrames);
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * kFrames));
  state.counters["copy_ms"] = copy_ms / static_cast<double>(state.iterations() * kFrames);
}

BENCHMARK(BM_Allocate)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Integrate)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Raycast)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RaycastHinted)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RaycastPipeline)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_WarpRaycast)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Track)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ExtractMesh)->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK(BM_MeshRender)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ReadFrames)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ReadAheadBesideALoop)
    ->Arg(0)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
}  // namespace hivox

BENCHMARK_MAIN();

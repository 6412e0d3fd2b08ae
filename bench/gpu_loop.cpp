// The online loop on a CUDA device over a sequence held in memory, per-stage times and the frame
// rate, optionally with the CPU loop on the same frames for a same-run ratio.
//
//   hivox_gpu_loop synthetic:desk?frames=300 --levels 1            # fixed 2 mm, tracked
//   hivox_gpu_loop data/tum_fr1_rpy --handover 50 --cpu           # 3 levels from a CPU-refined map
//   hivox_gpu_loop synthetic:desk?frames=150 --poses gt --mesh    # then mesh it, both ways
//   hivox_gpu_loop synthetic:desk?frames=150 --poses gt --render  # then render it, both ways
//   hivox_gpu_loop data/tum_fr1_rpy --read-threads 8              # frames decoded as it runs
//
// `--handover K` runs frames [0, K) through the CPU reconstruction, copies its map to the device
// and times frames [K, N) there (the device refines the hierarchy from then on). Times are the
// host's wall clock around each stage, the device synchronised at its end; the first `--warmup`
// timed frames are left out of the means. With `--read-threads N` the device's frames are read
// from the dataset as the loop goes (0: each in turn; N: ahead on N threads, as a run reads), and
// the loop's wall-clock rate includes decoding them.

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <memory>
#include <numeric>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "hivox/core/error.h"
#include "hivox/core/timer.h"
#include "hivox/cuda/gpu_reconstruction.h"
#include "hivox/eval/trajectory_eval.h"
#include "hivox/io/dataset.h"
#include "hivox/io/read_ahead.h"
#include "hivox/mesh/extract_mesh.h"
#include "hivox/pipeline/reconstruction.h"
#include "hivox/raycast/raycaster.h"

namespace {

using namespace hivox;

/// The mean stage times of the frames after the first `warmup`, and the median frame time.
struct Means {
  StageTimes mean;
  double median_total_ms = 0;
  int frames = 0;
};

Means means_of(const std::vector<FrameStats>& frames, int warmup) {
  Means m;
  const std::span<const FrameStats> timed =
      std::span(frames).subspan(std::min(frames.size(), static_cast<std::size_t>(warmup)));
  m.mean = mean_stage_times(timed);
  m.frames = static_cast<int>(timed.size());
  std::vector<double> totals;
  for (const FrameStats& f : timed) totals.push_back(f.total_ms);
  if (totals.empty()) return m;
  std::nth_element(totals.begin(), totals.begin() + totals.size() / 2, totals.end());
  m.median_total_ms = totals[totals.size() / 2];
  return m;
}

std::optional<double> ate_of(const std::vector<StampedPose>& gt,
                             const std::vector<StampedPose>& est) {
  if (gt.size() < 3 || est.size() < 3) return std::nullopt;
  try {
    return evaluate_ate(gt, est).rmse_m;
  } catch (const Error&) {
    return std::nullopt;
  }
}

std::string mm(const std::optional<double>& m) {
  return m ? std::to_string(*m * 1e3) + " mm" : std::string("n/a");
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"hivox's online loop on a CUDA device"};
  std::string spec;
  int frames = 0, handover = 0, levels = 3, warmup = 5, read_threads = -1;
  float voxel_m = 0.002f;
  std::string poses = "track";
  bool cpu = false, mesh = false, render = false, gn_on_host = false, no_coarse_grid = false,
       graph = false, refine_after = false, refine_in_order = false, upload_beside = false,
       queued_marches = false;
  int split_marches = 0;
  int raycast_registers = 0;
  int allocation_pixels = 1;
  int model_subsample = TrackParams{}.model_subsample;
  int64_t max_blocks = 1 << 20;
  std::string json;
  app.add_option("dataset", spec, "dataset folder or synthetic:... spec")->required();
  app.add_option("--frames", frames, "frames to read (0: all)");
  app.add_option("--handover", handover,
                 "frames fused on the CPU first (with refinement) before the device takes over");
  app.add_option("--levels", levels, "resolution levels");
  app.add_option("--voxel-size", voxel_m, "finest voxel size, metres");
  app.add_option("--poses", poses, "track (ICP) or gt (the dataset's poses)")
      ->check(CLI::IsMember({"track", "gt"}));
  app.add_option("--warmup", warmup, "timed frames left out of the means");
  app.add_option("--max-blocks", max_blocks, "block pool capacity");
  app.add_option("--model-subsample", model_subsample,
                 "the tracking model's raycast at 1/N of the frame's resolution (1, 2 or 4)");
  app.add_flag("--cpu", cpu, "also run the CPU loop on the same frames (same handover)");
  app.add_flag("--gn-on-host", gn_on_host,
               "tracking's Gauss-Newton steps on the host, each pass's sums read back "
               "(GpuReconstruction::set_gauss_newton_on_device(false))");
  app.add_flag("--tracking-graph", graph,
               "tracking's ICP passes launched as one CUDA graph, recorded at the second tracked "
               "frame (GpuReconstruction::set_tracking_graph)");
  app.add_option("--split-marches", split_marches,
                 "split a warp's marches across its lanes where at most this many of its rays "
                 "march (GpuReconstruction::set_split_marches; 0: each ray its own)");
  app.add_flag("--queued-marches", queued_marches,
               "the raycast as two kernels: the rays searched at their hints, then each ray whose "
               "search failed marched across a warp's lanes (GpuReconstruction::"
               "set_queued_marches)");
  app.add_option("--raycast-registers", raycast_registers,
                 "at most this many registers a thread of the raycast's kernel: 128, 96, 80 or "
                 "64, more warps at once (GpuReconstruction::set_raycast_registers; 0: the "
                 "compiler's choice)");
  app.add_option("--allocation-pixels", allocation_pixels,
                 "pixels a thread of the allocation walks: 1, 2 (2x1) or 4 (2x2), skipping the "
                 "look-ups of blocks it has seen (GpuReconstruction::set_allocation_pixels)");
  app.add_flag("--no-coarse-grid", no_coarse_grid,
               "raycasts cross unallocated space block by block (no coarse occupancy grid)");
  CLI::Option* after =
      app.add_flag("--refine-after-raycast", refine_after,
                   "refine after each frame's model raycast, on a stream of its own beside it "
                   "(ReconstructionParams::refine_after_raycast; --cpu does the same)");
  app.add_flag("--refine-in-order", refine_in_order,
               "with --refine-after-raycast: the refinement after the raycast on the loop's "
               "stream, not beside it (GpuReconstruction::set_refine_beside_raycast(false))")
      ->needs(after);
  app.add_flag("--upload-beside", upload_beside,
               "frames go up and their tracking pyramids are made on a stream of their own, "
               "beside the raycast (GpuReconstruction::set_upload_beside_raycast)");
  app.add_flag("--mesh", mesh,
               "after the loop, time meshing the map on the device and, downloaded, on the host");
  app.add_flag("--render", render,
               "after the loop, time a render from the last pose (the depth camera) on the "
               "device and, the map downloaded, on the host");
  app.add_option("--read-threads", read_threads,
                 "read the device's frames from the dataset as the loop goes: 0 each in turn, N "
                 "ahead on N threads (default: from memory)");
  app.add_option("--json", json, "write the results here");
  CLI11_PARSE(app, argc, argv);

  try {
    const std::unique_ptr<DatasetReader> reader = open_dataset(spec);
    const CameraRig& rig = reader->info().rig;
    const std::size_t n =
        frames > 0 ? std::min<std::size_t>(static_cast<std::size_t>(frames), reader->size())
                   : reader->size();
    std::vector<RgbdFrame> data;
    Stopwatch read;
    for (std::size_t i = 0; i < n; ++i) data.push_back(reader->read(i));
    std::printf("read %zu frames of %s (%dx%d) in %.1f s\n", n, spec.c_str(),
                rig.depth_camera.width, rig.depth_camera.height, read.elapsed_ms() / 1e3);
    const bool track = poses == "track";
    const bool has_gt = std::all_of(data.begin(), data.end(),
                                    [](const RgbdFrame& f) { return f.T_wc_gt.has_value(); });
    if (!track && !has_gt) throw Error(ErrorCode::InvalidArgument, "--poses gt: no ground truth");
    const Pose first = has_gt ? *data[0].T_wc_gt : Pose::Identity();

    ReconstructionParams params;
    params.map.levels = levels;
    params.map.voxel_size_m = voxel_m;
    params.map.max_blocks = max_blocks;
    params.track.model_subsample = model_subsample;
    params.raycast.tuning.coarse_skipping = !no_coarse_grid;
    params.refine_after_raycast = refine_after;
    const std::size_t k =
        static_cast<std::size_t>(std::clamp<int>(handover, 0, static_cast<int>(n)));

    // Frames [0, k) on the CPU; its map goes to the device (and, with --cpu, it continues).
    ReconstructionParams cpu_params = params;
    cpu_params.device = Device::cpu();
    Reconstruction cpu_loop(cpu_params, rig);
    Stopwatch handover_watch;
    for (std::size_t i = 0; i < k; ++i) {
      if (track)
        cpu_loop.track_and_integrate(data[i], 0.0, first);
      else
        cpu_loop.integrate(data[i], *data[i].T_wc_gt);
    }
    if (k > 0)
      std::printf("CPU: %zu frames fused before the handover (%.1f s), %lld blocks (%s)\n", k,
                  handover_watch.elapsed_ms() / 1e3,
                  static_cast<long long>(cpu_loop.map().blocks_in_use()),
                  [&] {
                    std::string s;
                    for (int64_t b : cpu_loop.map().blocks_per_level())
                      s += (s.empty() ? "" : " / ") + std::to_string(b);
                    return s;
                  }()
                      .c_str());

    params.device = Device::cuda();
    std::unique_ptr<cuda::GpuReconstruction> gpu =
        k > 0 ? std::make_unique<cuda::GpuReconstruction>(
                    params, rig, cpu_loop.map(),
                    MapSession{static_cast<int64_t>(k), cpu_loop.trajectory().back().T_wc, {}})
              : std::make_unique<cuda::GpuReconstruction>(params, rig);
    gpu->set_gauss_newton_on_device(!gn_on_host);
    gpu->set_split_marches(split_marches);
    gpu->set_raycast_registers(raycast_registers);
    gpu->set_allocation_pixels(allocation_pixels);
    gpu->set_tracking_graph(graph);
    gpu->set_upload_beside_raycast(upload_beside);
    gpu->set_refine_beside_raycast(!refine_in_order);
    gpu->set_queued_marches(queued_marches);
    const int registers = gpu->raycast_registers();
    std::printf(
        "device: %s; Gauss-Newton on the %s; coarse occupancy grid %s; split marches %d%s; "
        "refinement %s the raycast; frames up %s; the model raycast at 1/%d; the raycast's "
        "kernel takes %d registers a thread (at most %s)\n",
        cuda::device_name(0).c_str(), gn_on_host ? "host" : "device", no_coarse_grid ? "off" : "on",
        split_marches, queued_marches ? "; marches queued" : "",
        refine_after ? (refine_in_order ? "after (in order)" : "after (beside)") : "before",
        upload_beside ? "beside the raycast" : "after the raycast", model_subsample, registers,
        raycast_registers > 0 ? std::to_string(raycast_registers).c_str()
                              : "the compiler's choice");
    std::vector<StampedPose> gt;
    std::optional<ReadAhead> from_disk;
    if (read_threads >= 0)
      from_disk.emplace(*reader, k, n, ReadAhead::frames_for(read_threads), read_threads);
    RgbdFrame decoded;
    Stopwatch loop_watch;
    for (std::size_t i = k; i < n; ++i) {
      if (from_disk) decoded = from_disk->next();
      const RgbdFrame& f = from_disk ? decoded : data[i];
      if (has_gt) gt.push_back({f.timestamp_s, *f.T_wc_gt});
      if (track)
        gpu->track_and_integrate(f, first);
      else
        gpu->integrate(f, *f.T_wc_gt);
    }
    gpu->synchronize();  // the last frame's raycast
    const double wall_fps = static_cast<double>(n - k) / (loop_watch.elapsed_ms() / 1e3);
    std::printf("the loop's wall clock: %.0f fps, frames %s\n", wall_fps,
                read_threads < 0 ? "from memory"
                : read_threads == 0
                    ? "read in turn"
                    : ("read ahead on " + std::to_string(read_threads) + " threads").c_str());
    const Means g = means_of(gpu->frames(), warmup);
    int64_t lost = 0, splits = 0, merges = 0;
    for (const FrameStats& f : gpu->frames()) {
      lost += !f.fused;
      splits += f.splits;
      merges += f.merges;
    }
    const std::optional<double> gpu_ate = has_gt ? ate_of(gt, gpu->trajectory()) : std::nullopt;
    std::printf(
        "GPU: %d frames timed (%d warm-up left out), %s poses, %d levels from %.1f mm\n"
        "  mean ms: upload %.3f  track %.3f  allocate %.3f  integrate %.3f  refine %.3f  "
        "raycast %.3f  "
        "total %.3f (median %.3f)\n"
        "  %.0f fps (mean), %.0f fps (median); %lld blocks (%lld splits, %lld merges); map %.1f "
        "MiB, all device buffers %.1f MiB; %lld frames lost; ATE %s\n",
        g.frames, warmup, poses.c_str(), levels, voxel_m * 1e3, g.mean.upload_ms, g.mean.track_ms,
        g.mean.allocate_ms, g.mean.integrate_ms, g.mean.refine_ms, g.mean.raycast_ms,
        g.mean.total_ms, g.median_total_ms, 1e3 / g.mean.total_ms, 1e3 / g.median_total_ms,
        static_cast<long long>(gpu->blocks_in_use()), static_cast<long long>(splits),
        static_cast<long long>(merges), gpu->map_memory_bytes() / 1048576.0,
        gpu->device_memory_bytes() / 1048576.0, static_cast<long long>(lost), mm(gpu_ate).c_str());

    // Meshing the final map: on the device (its second call timed: the first loads the kernels),
    // and downloaded, on the host.
    double mesh_ms = 0, mesh_download_ms = 0, mesh_host_ms = 0;
    int64_t mesh_triangles = 0;
    if (mesh) {
      gpu->extract_mesh();
      Stopwatch watch;
      const TriangleMesh on_device = gpu->extract_mesh();
      mesh_ms = watch.lap_ms();
      const std::unique_ptr<VoxelBlockMap> host_map = gpu->download_map();
      mesh_download_ms = watch.lap_ms();
      const TriangleMesh on_host = extract_mesh(*host_map);
      mesh_host_ms = watch.lap_ms();
      mesh_triangles = on_device.triangle_count();
      std::printf(
          "mesh: %lld triangles, %lld vertices on the device in %.1f ms; the map downloaded in "
          "%.1f ms and meshed on the host in %.1f ms (%lld triangles)\n",
          static_cast<long long>(mesh_triangles), static_cast<long long>(on_device.vertex_count()),
          mesh_ms, mesh_download_ms, mesh_host_ms,
          static_cast<long long>(on_host.triangle_count()));
    }

    // A render of the final map from the last pose: on the device (its second call timed), and
    // the map downloaded and raycast on the host (what a render did before it ran on the device).
    double render_ms = 0, render_download_ms = 0, render_host_ms = 0;
    if (render && !gpu->trajectory().empty()) {
      const Pose T_wc = gpu->trajectory().back().T_wc;
      const DepthRange& range = params.fusion.depth_range;
      gpu->render(rig.depth_camera, T_wc, range);
      Stopwatch watch;
      const RaycastResult on_device = gpu->render(rig.depth_camera, T_wc, range);
      render_ms = watch.lap_ms();
      const std::unique_ptr<VoxelBlockMap> host_map = gpu->download_map();
      render_download_ms = watch.lap_ms();
      Raycaster raycaster(params.raycast);
      const RaycastResult& on_host = raycaster.raycast(*host_map, rig.depth_camera, T_wc, range);
      render_host_ms = watch.lap_ms();
      auto hits = [](const RaycastResult& r) {
        return std::count_if(r.depth_m.data(), r.depth_m.data() + r.depth_m.size(),
                             [](float d) { return d > 0.0f; });
      };
      std::printf(
          "render %dx%d: on the device in %.2f ms (%lld hits); the map downloaded in %.1f ms "
          "and raycast on the host in %.1f ms (%lld hits)\n",
          rig.depth_camera.width, rig.depth_camera.height, render_ms,
          static_cast<long long>(hits(on_device)), render_download_ms, render_host_ms,
          static_cast<long long>(hits(on_host)));
    }

    double cpu_ms = 0;
    std::optional<double> cpu_ate;
    int64_t cpu_map_bytes = 0;
    if (cpu) {
      Stopwatch watch;
      for (std::size_t i = k; i < n; ++i) {
        if (track)
          cpu_loop.track_and_integrate(data[i], 0.0, first);
        else
          cpu_loop.integrate(data[i], *data[i].T_wc_gt);
      }
      cpu_ms = watch.elapsed_ms() / static_cast<double>(n - k);
      std::vector<StampedPose> est(cpu_loop.trajectory().begin() + static_cast<std::ptrdiff_t>(k),
                                   cpu_loop.trajectory().end());
      if (has_gt) cpu_ate = ate_of(gt, est);
      cpu_map_bytes = cpu_loop.map().memory_bytes();
      std::printf(
          "CPU: %.3f ms a frame (%.1f fps, refinement %s), %lld blocks, map %.1f MiB; ATE %s; "
          "GPU/CPU speed-up %.1fx\n",
          cpu_ms, 1e3 / cpu_ms, levels > 1 ? "on" : "n/a",
          static_cast<long long>(cpu_loop.map().blocks_in_use()), cpu_map_bytes / 1048576.0,
          mm(cpu_ate).c_str(), cpu_ms / g.mean.total_ms);
    }
    if (!json.empty()) {
      std::ofstream out(json);
      out << "{\"dataset\": \"" << spec << "\", \"device\": \"" << cuda::device_name(0)
          << "\", \"levels\": " << levels << ", \"voxel_size_m\": " << voxel_m << ", \"poses\": \""
          << poses << "\", \"gauss_newton_on_device\": " << (gn_on_host ? "false" : "true")
          << ", \"coarse_grid\": " << (no_coarse_grid ? "false" : "true")
          << ", \"split_marches\": " << split_marches
          << ", \"queued_marches\": " << (queued_marches ? "true" : "false")
          << ", \"model_subsample\": " << model_subsample
          << ", \"raycast_registers_at_most\": " << raycast_registers
          << ", \"raycast_registers\": " << registers
          << ", \"allocation_pixels\": " << allocation_pixels
          << ", \"tracking_graph\": " << (graph ? "true" : "false")
          << ", \"refine_after_raycast\": " << (refine_after ? "true" : "false")
          << ", \"refine_beside_raycast\": " << (refine_in_order ? "false" : "true")
          << ", \"upload_beside_raycast\": " << (upload_beside ? "true" : "false")
          << ", \"handover\": " << k << ", \"frames_timed\": " << g.frames
          << ", \"read_threads\": " << read_threads << ", \"wall_fps\": " << wall_fps
          << ", \"mean_ms\": {\"upload\": " << g.mean.upload_ms
          << ", \"track\": " << g.mean.track_ms << ", \"allocate\": " << g.mean.allocate_ms
          << ", \"integrate\": " << g.mean.integrate_ms << ", \"refine\": " << g.mean.refine_ms
          << ", \"raycast\": " << g.mean.raycast_ms << ", \"total\": " << g.mean.total_ms
          << "}, \"median_total_ms\": " << g.median_total_ms
          << ", \"blocks\": " << gpu->blocks_in_use()
          << ", \"map_bytes\": " << gpu->map_memory_bytes()
          << ", \"device_bytes\": " << gpu->device_memory_bytes() << ", \"lost\": " << lost
          << ", \"ate_m\": " << (gpu_ate ? std::to_string(*gpu_ate) : "null")
          << ", \"mesh_ms\": " << mesh_ms << ", \"mesh_download_ms\": " << mesh_download_ms
          << ", \"mesh_host_ms\": " << mesh_host_ms << ", \"mesh_triangles\": " << mesh_triangles
          << ", \"render_ms\": " << render_ms << ", \"render_download_ms\": " << render_download_ms
          << ", \"render_host_ms\": " << render_host_ms << ", \"cpu_ms\": " << cpu_ms
          << ", \"cpu_map_bytes\": " << cpu_map_bytes
          << ", \"cpu_ate_m\": " << (cpu_ate ? std::to_string(*cpu_ate) : "null") << "}\n";
    }
  } catch (const Error& e) {
    std::fprintf(stderr, "hivox_gpu_loop: %s\n", e.what());
    return 1;
  }
  return 0;
}

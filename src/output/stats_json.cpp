#include "hivox/output/stats_json.h"

#include <fstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "hivox/core/error.h"
#include "hivox/core/version.h"
#include "hivox/io/atomic_file.h"

namespace hivox {

void write_stats_json(const std::filesystem::path& path, const Reconstruction& rec,
                      const RunInfo& run) {
  using nlohmann::json;
  const auto& frames = rec.frame_stats();
  json per_frame = json::array();
  for (const FrameStats& f : frames) {
    per_frame.push_back({{"index", f.index},
                         {"timestamp", f.timestamp_s},
                         {"blocks_total", f.blocks_total},
                         {"blocks_per_level", f.blocks_per_level},
                         {"visible_blocks", f.visible_blocks},
                         {"new_blocks", f.new_blocks},
                         {"dropped_blocks", f.dropped_blocks},
                         {"splits", f.splits},
                         {"merges", f.merges},
                         {"refine_waiting", f.refine_waiting},
                         {"valid_pixels", f.valid_pixels},
                         {"raycast_hits", f.raycast_hits},
                         {"raycast_hits_at_hint", f.raycast_hits_at_hint},
                         {"tracking", std::string(to_string(f.tracking))},
                         {"fused", f.fused},
                         {"track_inlier_ratio", f.track_inlier_ratio},
                         {"track_rms_m", f.track_rms_m},
                         {"track_condition", f.track_condition},
                         {"track_iterations", f.track_iterations},
                         {"timing_ms",
                          {{"read", f.read_ms},
                           {"upload", f.upload_ms},
                           {"track", f.track_ms},
                           {"allocate", f.allocate_ms},
                           {"integrate", f.integrate_ms},
                           {"refine", f.refine_ms},
                           {"raycast", f.raycast_ms},
                           {"total", f.total_ms}}}});
  }
  const VoxelBlockMap& map = rec.map();
  json j;
  j["hivox_version"] = std::string(library_version());
  j["dataset"] = run.dataset;
  const PinholeCamera& cam = rec.rig().depth_camera;
  j["camera"] = {{"fx", cam.fx}, {"fy", cam.fy},       {"cx", cam.cx},
                 {"cy", cam.cy}, {"width", cam.width}, {"height", cam.height}};
  j["depth_scale"] = run.depth_scale;
  if (!run.config_json.empty()) j["config"] = json::parse(run.config_json);
  j["poses"] = run.pose_source;
  j["threads"] = run.threads;
  if (run.gpu)
    j["gpu"] = {{"device", run.gpu->device.to_string()},
                {"name", run.gpu->name},
                {"memory_bytes", run.gpu->memory_bytes},
                {"compute_capability",
                 fmt::format("{}.{}", run.gpu->compute_major, run.gpu->compute_minor)},
                {"multiprocessors", run.gpu->multiprocessors}};
  j["parameters"] = run.parameters;
  j["frames"] = frames.size();
  j["frames_fused"] =
      run.frames_fused >= 0 ? run.frames_fused : static_cast<int64_t>(frames.size());
  j["skipped_frames"] = run.skipped_frames;
  j["bad_frames"] = run.bad_frames;
  j["end"] = run.end;
  j["warnings"] = run.warnings;
  j["unusable"] = run.unusable;
  const StageTimes t = mean_stage_times(frames);
  j["fps"] = t.fps();
  j["fps_wall"] = run.wall_s > 0 ? static_cast<double>(frames.size()) / run.wall_s : 0.0;
  j["timing_ms"] = {{"read", t.read_ms},           {"upload", t.upload_ms},
                    {"track", t.track_ms},         {"allocate", t.allocate_ms},
                    {"integrate", t.integrate_ms}, {"refine", t.refine_ms},
                    {"raycast", t.raycast_ms},     {"total", t.total_ms}};
  j["blocks_total"] = map.blocks_in_use();
  j["blocks_per_level"] = map.blocks_per_level();
  j["peak_blocks_total"] = rec.peak_blocks();
  j["dropped_blocks"] = map.dropped_blocks();
  j["bytes_per_voxel"] = map.params().bytes_per_voxel();
  j["memory_bytes"] = map.memory_bytes();
  j["voxel_size_m"] = map.params().voxel_size_m;
  j["levels"] = map.params().levels;
  j["truncation_m"] = rec.params().map.truncation_m;
  int64_t splits = 0, merges = 0;
  for (const FrameStats& f : frames) {
    splits += f.splits;
    merges += f.merges;
  }
  const TrackingCounts& tc = rec.tracking_counts();
  j["tracking"] = {{"good", tc.good}, {"poor", tc.poor}, {"lost", tc.lost}};
  if (run.ate_rmse_m) j["ate_rmse_m"] = *run.ate_rmse_m;
  j["splits"] = splits;
  j["merges"] = merges;
  if (map.params().levels > 1) j["refine"] = rec.params().refine.to_string();
  j["per_frame"] = std::move(per_frame);
  AtomicFile file(path);
  std::ofstream out(file.temp_path());
  if (!out) fail(ErrorCode::Io, "{}: cannot open for writing", path.string());
  out << j.dump(1) << "\n";
  out.close();
  if (!out) fail(ErrorCode::Io, "{}: write failed", path.string());
  file.commit();
}

}  // namespace hivox

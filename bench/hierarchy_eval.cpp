// The hierarchy experiment (paper §VI): fuses one sequence three ways in lockstep --
// fixed finest grid, adaptive levels, fixed coarsest grid -- and reports blocks over time, the
// saving, time per stage, and accuracy (paper Table I): the mean |SDF| of each reconstruction at
// points on a reference surface (the exact surface for synthetic scenes, otherwise vertices of
// the fixed finest grid's mesh).
//
//   build/bench/hierarchy_eval DATASET [--voxel 0.002] [--levels 3] [--truncation 0.024]
//       [--frames N] [--csv blocks.csv] [--refine detail|det-cov]
//       [--depth-sampling bilinear|nearest] [--split-threshold M] [--merge-threshold M]

#include <cstdio>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "hivox/core/timer.h"
#include "hivox/eval/surface_eval.h"
#include "hivox/io/dataset.h"
#include "hivox/mesh/extract_mesh.h"
#include "hivox/pipeline/reconstruction.h"
#include "hivox/synth/synthetic_dataset.h"

using namespace hivox;

namespace {

struct Run {
  std::string name;
  std::unique_ptr<Reconstruction> rec;
};

/// The value after option `name`, if given.
std::optional<std::string> given(int argc, char** argv, const char* name) {
  for (int i = 1; i + 1 < argc; ++i)
    if (std::string(argv[i]) == name) return argv[i + 1];
  return std::nullopt;
}

std::string arg(int argc, char** argv, const char* name, const char* fallback) {
  return given(argc, argv, name).value_or(fallback);
}

}  // namespace

int main(int argc, char** argv) try {
  if (argc < 2) {
    std::fprintf(stderr,
                 "usage: hierarchy_eval DATASET [--voxel M] [--levels N] [--truncation M] "
                 "[--frames N] [--csv FILE] [--refine detail|det-cov] [--depth-sampling "
                 "bilinear|nearest] [--split-threshold M] [--merge-threshold M]\n");
    return 2;
  }
  const std::string dataset = argv[1];
  const float voxel = std::stof(arg(argc, argv, "--voxel", "0.002"));
  const int levels = std::stoi(arg(argc, argv, "--levels", "3"));
  const float mu = std::stof(arg(argc, argv, "--truncation", "0.024"));
  const std::size_t frames = std::stoul(arg(argc, argv, "--frames", "0"));
  const std::string csv = arg(argc, argv, "--csv", "");
  const std::string criterion = arg(argc, argv, "--refine", "detail");
  DatasetParams dp;
  dp.max_frames = frames;
  const auto reader = open_dataset(dataset, dp);

  ReconstructionParams base;
  base.map.voxel_size_m = voxel;
  base.map.truncation_m = mu;
  if (const auto d = given(argc, argv, "--depth-sampling"))
    base.fusion.depth_sampling = parse_depth_sampling(*d);
  base.raycast_every_frame = false;
  base.map.max_blocks = 1 << 22;
  base.map.buckets_per_level = 1 << 22;
  base.map.excess_per_level = 1 << 21;
  ReconstructionParams fine = base, adaptive = base, coarse = base;
  fine.map.levels = 1;
  adaptive.map.levels = levels;
  if (criterion == "det-cov") adaptive.refine = RefineParams::paper();
  if (const auto t = given(argc, argv, "--split-threshold"))
    adaptive.refine.split_threshold = std::stof(*t);
  if (const auto t = given(argc, argv, "--merge-threshold"))
    adaptive.refine.merge_threshold = std::stof(*t);
  coarse.map.levels = 1;
  coarse.map.voxel_size_m = voxel * static_cast<float>(1 << (levels - 1));
  std::vector<Run> runs;
  runs.push_back({fmt::format("fixed {:g} mm", voxel * 1000),
                  std::make_unique<Reconstruction>(fine, reader->info().rig)});
  runs.push_back({fmt::format("adaptive ({} levels, {})", levels, criterion),
                  std::make_unique<Reconstruction>(adaptive, reader->info().rig)});
  runs.push_back({fmt::format("fixed {:g} mm", coarse.map.voxel_size_m * 1000),
                  std::make_unique<Reconstruction>(coarse, reader->info().rig)});

  std::ofstream out_csv;
  if (!csv.empty()) {
    out_csv.open(csv);
    out_csv << "frame,timestamp,fixed_fine_blocks,adaptive_blocks,adaptive_level0,adaptive_level1,"
               "adaptive_level2,fixed_coarse_blocks\n";
  }
  std::size_t used = 0;
  for (std::size_t i = 0; i < reader->size(); ++i) {
    const RgbdFrame frame = reader->read(i);
    if (!frame.T_wc_gt) continue;
    for (Run& r : runs) r.rec->integrate(frame, *frame.T_wc_gt);
    ++used;
    if (out_csv) {
      const auto& a = runs[1].rec->frame_stats().back();
      out_csv << i << ',' << fmt::format("{:.6f}", frame.timestamp_s) << ','
              << runs[0].rec->frame_stats().back().blocks_total << ',' << a.blocks_total;
      for (int l = 0; l < 3; ++l)
        out_csv << ','
                << (l < static_cast<int>(a.blocks_per_level.size()) ? a.blocks_per_level[l] : 0);
      out_csv << ',' << runs[2].rec->frame_stats().back().blocks_total << '\n';
    }
    if ((i + 1) % 100 == 0) std::fprintf(stderr, "frame %zu/%zu\n", i + 1, reader->size());
  }

  // Reference surface points.
  std::vector<Vec3f> points;
  std::string reference;
  if (const auto* synthetic = dynamic_cast<const SyntheticDataset*>(reader.get())) {
    reference = "exact surface (clean renders of 6 poses, every 4th pixel)";
    const PinholeCamera cam = synthetic->camera();
    for (std::size_t i = 0; i < synthetic->size();
         i += std::max<std::size_t>(1, synthetic->size() / 6)) {
      const RenderedFrame clean = synthetic->render_clean(i);
      for (int y = 0; y < cam.height; y += 4)
        for (int x = 0; x < cam.width; x += 4) {
          const float d = clean.depth_m(x, y);
          if (d <= 0.0f || d > base.fusion.depth_range.max_m) continue;
          const Eigen::Vector3d p =
              clean.T_wc * Eigen::Vector3d((x - cam.cx) / cam.fx * d, (y - cam.cy) / cam.fy * d, d);
          points.push_back(
              {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())});
        }
    }
  } else {
    const TriangleMesh mesh = extract_mesh(runs[0].rec->map());
    const std::size_t step = std::max<std::size_t>(1, mesh.positions_w.size() / 2000000);
    for (std::size_t i = 0; i < mesh.positions_w.size(); i += step)
      points.push_back(mesh.positions_w[i]);
    reference = fmt::format("vertices of the {} mesh ({} of {})", runs[0].name, points.size(),
                            mesh.positions_w.size());
  }

  std::printf("%s: %zu frames with poses; reference: %s\n\n", dataset.c_str(), used,
              reference.c_str());
  std::printf(
      "| map | blocks | per level | peak | memory MiB | mean abs SDF mm | coverage | ms/frame "
      "(alloc, integrate, refine) |\n");
  std::printf("| --- | ---: | --- | ---: | ---: | ---: | ---: | --- |\n");
  for (const Run& r : runs) {
    const SurfaceEval e = evaluate_at_points(r.rec->map(), points);
    const StageTimes t = mean_stage_times(r.rec->frame_stats());
    const auto per = r.rec->map().blocks_per_level();
    std::string per_level;
    for (std::size_t l = 0; l < per.size(); ++l)
      per_level += fmt::format("{}{}", l ? " / " : "", per[l]);
    std::printf("| %s | %ld | %s | %ld | %.0f | %.3f | %.3f | %.1f (%.1f, %.1f, %.1f) |\n",
                r.name.c_str(), static_cast<long>(r.rec->map().blocks_in_use()), per_level.c_str(),
                static_cast<long>(r.rec->peak_blocks()), r.rec->map().memory_bytes() / 1048576.0,
                1000.0 * e.mean_distance_m,
                static_cast<double>(e.found) / static_cast<double>(e.points), t.total_ms,
                t.allocate_ms, t.integrate_ms, t.refine_ms);
  }
  const double saving = 1.0 - static_cast<double>(runs[1].rec->map().blocks_in_use()) /
                                  static_cast<double>(runs[0].rec->map().blocks_in_use());
  const double time_ratio = mean_stage_times(runs[1].rec->frame_stats()).total_ms /
                            mean_stage_times(runs[0].rec->frame_stats()).total_ms;
  std::printf("\nsaving vs %s: %.1f %% of blocks; adaptive frame time / fixed finest: %.2f\n",
              runs[0].name.c_str(), 100.0 * saving, time_ratio);
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "hierarchy_eval: %s\n", e.what());
  return 1;
}

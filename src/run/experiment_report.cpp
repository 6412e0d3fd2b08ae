// report.json and report.md of an experiment (experiment.h).

#include <algorithm>
#include <filesystem>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "hivox/run/experiment.h"

namespace hivox {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

json times_json(const StageTimes& t) {
  return {{"track_ms", t.track_ms},
          {"allocate_ms", t.allocate_ms},
          {"integrate_ms", t.integrate_ms},
          {"refine_ms", t.refine_ms},
          {"raycast_ms", t.raycast_ms},
          {"total_ms", t.total_ms},
          {"fps", t.fps()}};
}

json distance_json(const DistanceStats& d) {
  return {{"mean_m", d.mean_m}, {"median_m", d.median_m}, {"rmse_m", d.rmse_m}, {"max_m", d.max_m}};
}

std::string mm(double m, int digits = 3) {
  return fmt::format("{:.{}f}", m * 1e3, digits);
}

}  // namespace

std::string experiment_json(const ExperimentResult& r, const ExperimentParams& p) {
  json configs = json::array();
  for (const ConfigResult& c : r.configs) {
    const MapParams& m = c.config.params.map;
    json j = {
        {"name", c.config.name},
        {"slug", c.config.slug},
        {"voxel_size_m", m.voxel_size_m},
        {"levels", m.levels},
        {"truncation_m", m.truncation_m},
        {"settings", c.config.params.to_string()},
        {"frames_fused", c.run.frames_fused},
        {"blocks", c.blocks},
        {"peak_blocks", c.peak_blocks},
        {"blocks_per_level", c.blocks_per_level},
        {"memory_mib", c.memory_mib},
        {"dropped_blocks", c.dropped_blocks},
        {"block_saving", c.block_saving},
        {"times", times_json(c.times)},
        {"sdf_error",
         {{"mean_m", c.sdf.mean_abs_sdf_m},
          {"median_m", c.sdf.median_abs_sdf_m},
          {"rmse_m", c.sdf.rmse_m},
          {"coverage", c.sdf.coverage},
          {"ratio_to_coarsest_fixed", c.sdf_ratio},
          {"points_per_level", c.sdf.points_per_level},
          {"mean_per_level_m", c.sdf.mean_abs_sdf_per_level_m}}},
        {"mesh_vertices", c.run.mesh_vertices},
        {"mesh_triangles", c.run.mesh_triangles},
        {"warnings", c.run.warnings},
    };
    if (c.mesh_eval) {
      json f = json::array();
      for (const FScore& s : c.mesh_eval->fscores)
        f.push_back({{"threshold_m", s.threshold_m},
                     {"precision", s.precision},
                     {"recall", s.recall},
                     {"fscore", s.fscore}});
      j["mesh_eval"] = {{"accuracy", distance_json(c.mesh_eval->accuracy)},
                        {"completeness", distance_json(c.mesh_eval->completeness)},
                        {"chamfer_m", c.mesh_eval->chamfer_m},
                        {"reference_observed", c.mesh_eval->reference_kept},
                        {"fscores", f}};
    }
    if (c.tracked) {
      j["tracked"] = {{"times", times_json(c.tracked_times)},
                      {"frames_fused", c.tracked->frames_fused},
                      {"frames_lost", c.tracked->frames_lost}};
      if (c.tracked->ate)
        j["tracked"]["ate"] = {{"rmse_m", c.tracked->ate->rmse_m},
                               {"mean_m", c.tracked->ate->mean_m},
                               {"median_m", c.tracked->ate->median_m},
                               {"max_m", c.tracked->ate->max_m}};
    }
    configs.push_back(std::move(j));
  }
  const json out = {{"dataset", r.dataset},
                    {"frames", r.frames},
                    {"poses", r.poses},
                    {"first_frame", p.first_frame},
                    {"sdf_samples", r.sdf_samples},
                    {"sdf_seed", p.sdf.seed},
                    {"reference_mesh", p.reference_mesh.string()},
                    {"reference_observed_views", r.reference_observed_views},
                    {"stopped", r.stopped},
                    {"wall_s", r.wall_s},
                    {"configs", configs}};
  return out.dump(2) + "\n";
}

std::string experiment_markdown(const ExperimentResult& r, const ExperimentParams& p) {
  std::string md = fmt::format("# hivox experiment: {}\n\n", r.dataset);
  md += fmt::format(
      "{} frames{}, poses: {}; every configuration fused the same frames from the same poses. "
      "The first configuration is the reference of the block saving and of the sdf-error "
      "(paper Table I): {} points sampled uniformly on its mesh, where each map's |SDF| is "
      "read.{}\n\n",
      r.frames, p.first_frame ? fmt::format(" from frame {}", p.first_frame) : "", r.poses,
      r.sdf_samples,
      r.stopped ? " **The experiment was stopped early: only what finished is reported.**" : "");

  md += "## Blocks and memory (paper Table II, Fig. 6)\n\n";
  md +=
      "| configuration | blocks at the end | per level (finest first) | peak | memory MiB | "
      "saving vs first |\n| --- | ---: | --- | ---: | ---: | ---: |\n";
  for (const ConfigResult& c : r.configs) {
    std::string per;
    for (std::size_t l = 0; l < c.blocks_per_level.size(); ++l)
      per += fmt::format("{}{}", l ? " / " : "", c.blocks_per_level[l]);
    md += fmt::format("| {} | {} | {} | {} | {:.0f} | {:.1f} % |\n", c.config.name, c.blocks, per,
                      c.peak_blocks, c.memory_mib, 100 * c.block_saving);
  }

  for (const ConfigResult& c : r.configs)
    if (c.dropped_blocks > 0)
      md += fmt::format(
          "\n**{}: {} blocks could not be allocated (the block pool or hash table was full); "
          "raise --max-blocks for a fair comparison.**\n",
          c.config.name, c.dropped_blocks);

  const int coarse = r.coarsest_fixed;
  md += "\n## Accuracy: sdf-error (paper Table I)\n\n";
  md += fmt::format(
      "Mean |SDF| at the points on the {} mesh, mm; ratio: to the coarsest fixed grid ({}).\n\n",
      r.configs.empty() ? "first" : r.configs[0].config.name,
      coarse >= 0 ? r.configs[static_cast<std::size_t>(coarse)].config.name : "none");
  md +=
      "| configuration | mean mm | median mm | rms mm | ratio | coverage |\n"
      "| --- | ---: | ---: | ---: | ---: | ---: |\n";
  for (const ConfigResult& c : r.configs) {
    md += fmt::format("| {} | {} | {} | {} | {:.2f} | {:.1f} % |\n", c.config.name,
                      mm(c.sdf.mean_abs_sdf_m), mm(c.sdf.median_abs_sdf_m), mm(c.sdf.rmse_m),
                      c.sdf_ratio, 100 * c.sdf.coverage);
  }
  for (const ConfigResult& c : r.configs) {
    if (c.sdf.points_per_level.size() < 2) continue;
    md += fmt::format("\n{}, by the level storing the point:\n\n", c.config.name);
    md += "| level | voxel mm | points | mean |SDF| mm |\n| ---: | ---: | ---: | ---: |\n";
    for (std::size_t l = 0; l < c.sdf.points_per_level.size(); ++l)
      md += fmt::format("| {} | {:g} | {} | {} |\n", l,
                        1e3 * c.config.params.map.voxel_size_at(static_cast<int>(l)),
                        c.sdf.points_per_level[l], mm(c.sdf.mean_abs_sdf_per_level_m[l]));
  }

  if (!p.reference_mesh.empty()) {
    md += fmt::format("\n## Mesh against the reference mesh {}\n\n", p.reference_mesh.string());
    md +=
        "Accuracy: the mesh's points to the reference; completeness: the reference's points to "
        "the mesh (mm)";
    if (r.reference_observed_views > 0 && !r.configs.empty() && r.configs[0].mesh_eval)
      md += fmt::format(
          ", over the part of the reference the sequence observed ({:.1f} % of its area: seen "
          "unoccluded in the depth of {} frames spread over the run)",
          100 * r.configs[0].mesh_eval->reference_kept, r.reference_observed_views);
    md += ".\n\n";
    std::string head =
        "| configuration | accuracy mean | median | completeness mean | median | "
        "Chamfer |";
    std::string rule = "| --- | ---: | ---: | ---: | ---: | ---: |";
    if (!r.configs.empty() && r.configs[0].mesh_eval)
      for (const FScore& f : r.configs[0].mesh_eval->fscores) {
        head += fmt::format(" F@{:g} mm |", f.threshold_m * 1e3);
        rule += " ---: |";
      }
    md += head + "\n" + rule + "\n";
    for (const ConfigResult& c : r.configs) {
      if (!c.mesh_eval) {
        md += fmt::format("| {} | (empty mesh) |\n", c.config.name);
        continue;
      }
      const MeshEvalResult& e = *c.mesh_eval;
      md += fmt::format("| {} | {} | {} | {} | {} | {} |", c.config.name, mm(e.accuracy.mean_m),
                        mm(e.accuracy.median_m), mm(e.completeness.mean_m),
                        mm(e.completeness.median_m), mm(e.chamfer_m));
      for (const FScore& f : e.fscores) md += fmt::format(" {:.1f} % |", 100 * f.fscore);
      md += "\n";
    }
  }

  md += "\n## Speed (ms per frame, this machine)\n\n";
  md +=
      "Same-pose runs (no tracking):\n\n| configuration | allocate | integrate | refine | "
      "total | fps |\n| --- | ---: | ---: | ---: | ---: | ---: |\n";
  for (const ConfigResult& c : r.configs)
    md += fmt::format("| {} | {:.1f} | {:.1f} | {:.1f} | {:.1f} | {:.1f} |\n", c.config.name,
                      c.times.allocate_ms, c.times.integrate_ms, c.times.refine_ms,
                      c.times.total_ms, c.times.fps());
  if (std::any_of(r.configs.begin(), r.configs.end(),
                  [](const ConfigResult& c) { return c.tracked.has_value(); })) {
    md +=
        "\nTracked runs (ICP, the whole loop), with the trajectory error against the ground "
        "truth:\n\n| configuration | track | fuse + refine | raycast | total | fps | ATE rmse "
        "cm | lost frames |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n";
    for (const ConfigResult& c : r.configs) {
      if (!c.tracked) continue;
      const StageTimes& t = c.tracked_times;
      md += fmt::format("| {} | {:.1f} | {:.1f} | {:.1f} | {:.1f} | {:.1f} | {} | {} |\n",
                        c.config.name, t.track_ms, t.allocate_ms + t.integrate_ms + t.refine_ms,
                        t.raycast_ms, t.total_ms, t.fps(),
                        c.tracked->ate ? fmt::format("{:.2f}", c.tracked->ate->rmse_m * 100) : "-",
                        c.tracked->frames_lost);
    }
  }

  std::string figures;
  for (const char* f : kExperimentFigures)
    if (fs::exists(p.out_dir / f)) figures += fmt::format("![{}]({})\n\n", f, f);
  md += "\n## Figures\n\n";
  md += figures.empty()
            ? "None yet: `python3 scripts/plot_experiment.py DIR` makes them (matplotlib); "
              "`hivox experiment` runs it when python3 with matplotlib is there.\n"
            : figures;
  md +=
      "\nFiles: `runs/<configuration>/` (each run's results and map), `renders/` (every map "
      "from the same overview and close-up poses), `blocks.csv`, `sdf_points.csv`, "
      "`report.json`.\n";
  return md;
}

}  // namespace hivox

// `hivox experiment DATASET`: the paper's experiments on one dataset (run/experiment.h) with a
// report and figures; `hivox eval sdf-error`: the paper's Table I score alone, from a dataset or
// from saved maps.

#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "config_file.h"
#include "dataset_options.h"
#include "hivox/core/error.h"
#include "hivox/core/log.h"
#include "hivox/core/threads.h"
#include "hivox/core/timer.h"
#include "hivox/io/atomic_file.h"
#include "hivox/io/map_file.h"
#include "hivox/mesh/extract_mesh.h"
#include "hivox/run/experiment.h"
#include "reconstruct_options.h"

namespace hivox::cli {

extern const char* const kPlotExperimentScript;

namespace {

namespace fs = std::filesystem;

/// Runs the built-in plotting script with `python` on `dir`; false (with the reason printed)
/// when it cannot.
bool draw_figures(const fs::path& dir) {
  const char* env = std::getenv("HIVOX_PYTHON");
  // Debian's interpreter first: python3-matplotlib installs for it, not for other pythons on PATH.
  const std::string python = env && *env                      ? env
                             : fs::exists("/usr/bin/python3") ? "/usr/bin/python3"
                                                              : "python3";
  int fds[2];
  if (pipe(fds) != 0) return false;
  const pid_t pid = fork();
  if (pid < 0) return false;
  if (pid == 0) {
    dup2(fds[0], 0);
    close(fds[0]);
    close(fds[1]);
    const std::string d = dir.string();
    execlp(python.c_str(), python.c_str(), "-", d.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  close(fds[0]);
  const std::string script = kPlotExperimentScript;
  // The child may exit early (no matplotlib): do not die of SIGPIPE.
  auto* previous = std::signal(SIGPIPE, SIG_IGN);
  std::size_t written = 0;
  while (written < script.size()) {
    const ssize_t n = write(fds[1], script.data() + written, script.size() - written);
    if (n <= 0) break;
    written += static_cast<std::size_t>(n);
  }
  close(fds[1]);
  std::signal(SIGPIPE, previous);
  int status = 0;
  waitpid(pid, &status, 0);
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return true;
  log::warn(
      "figures not made: {} could not run the plotting script (it needs matplotlib and numpy: "
      "scripts/install-deps installs python3-matplotlib; HIVOX_PYTHON picks another python). "
      "The tables are in {}; make the figures later with: python3 scripts/plot_experiment.py {}",
      python, (dir / "report.md").string(), dir.string());
  return false;
}

/// A configuration from a `config.json` that `hivox reconstruct` wrote: its settings parsed as
/// that command parses them.
ExperimentConfig config_from_file(const std::string& file, const std::string& dataset) {
  CLI::App app{"hivox"};
  ReconstructOptions o;
  CLI::App* cmd = app.add_subcommand("reconstruct");
  add_reconstruct_options(cmd, o);
  std::vector<std::string> args =
      expand_config_args({"hivox", "reconstruct", dataset, "--config", file}, app);
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  try {
    app.parse(static_cast<int>(argv.size()), argv.data());
  } catch (const CLI::ParseError& e) {
    fail(ErrorCode::InvalidData, "{}: {}", file, e.what());
  }
  const RunParams rp = run_params(o);
  fs::path p(file);
  std::string name =
      p.stem() == "config" && p.has_parent_path() && !p.parent_path().filename().empty()
          ? p.parent_path().filename().string()
          : p.stem().string();
  std::string slug;
  for (char c : name) {
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
    slug += (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ? c : '-';
  }
  return {name, "config-" + slug, rp.reconstruction};
}

struct ExperimentOptions {
  ReconstructOptions run;
  std::string out;
  std::string reference;
  std::string tracked = "auto";
  std::vector<std::string> configs;
  int64_t samples = SdfErrorParams{}.samples;
  int64_t mesh_samples = MeshEvalParams{}.samples;
  uint64_t seed = 1;
  bool overwrite = false;
  bool no_figures = false;
  CLI::Option* poses_option = nullptr;
};

/// The experiment the options describe on `reader`'s dataset: the fixed grids the adaptive
/// configuration implies, the adaptive one, then each --config; the same-pose runs' poses from
/// --poses when given, else the ground truth when the dataset has it, else tracking; the output
/// folder --out or out/<dataset name><default_suffix>.
ExperimentParams experiment_params(const ExperimentOptions& o, const DatasetReader& reader,
                                   const std::string& default_suffix) {
  ReconstructOptions adaptive = o.run;
  adaptive.out = "unused";  // run_params wants a folder; each run of the experiment has its own
  const RunParams base = run_params(adaptive);
  ExperimentParams params;
  params.configs = hierarchy_configs(base.reconstruction);
  for (const std::string& file : o.configs)
    params.configs.push_back(config_from_file(file, o.run.data.dataset));
  params.poses = o.poses_option != nullptr && o.poses_option->count() > 0
                     ? PoseSpec::parse(o.run.poses)
                     : PoseSpec::parse(reader.info().has_ground_truth ? "gt" : "icp");
  params.tracked = o.tracked == "always"  ? TrackedRuns::Always
                   : o.tracked == "never" ? TrackedRuns::Never
                                          : TrackedRuns::Auto;
  params.first_frame = o.run.first_frame;
  params.max_frames = o.run.frames;
  params.reference_mesh = o.reference;
  params.sdf.samples = o.samples;
  params.sdf.seed = o.seed;
  params.mesh_eval.samples = o.mesh_samples;
  params.mesh_eval.seed = o.seed;
  params.mesh = o.run.mesh;
  params.on_bad_frame = base.on_bad_frame;
  params.out_dir = o.out.empty() ? default_out_dir(o.run.data.dataset) + default_suffix : o.out;
  params.overwrite = o.overwrite;
  return params;
}

void print_table(const ExperimentResult& r) {
  fmt::print("\n{:<26} {:>9} {:>8} {:>10} {:>7} {:>8} {:>9}\n", "configuration", "blocks", "saving",
             "sdf mm", "ratio", "cover", "ms/frame");
  for (const ConfigResult& c : r.configs)
    fmt::print("{:<26} {:>9} {:>7.1f}% {:>10.3f} {:>7.2f} {:>7.1f}% {:>9.1f}\n", c.config.name,
               c.blocks, 100 * c.block_saving, 1e3 * c.sdf.mean_abs_sdf_m, c.sdf_ratio,
               100 * c.sdf.coverage, c.times.total_ms);
  for (const ConfigResult& c : r.configs) {
    if (c.mesh_eval)
      fmt::print("{:<26} mesh vs reference: accuracy {:.2f} mm, completeness {:.2f} mm (means)\n",
                 c.config.name, 1e3 * c.mesh_eval->accuracy.mean_m,
                 1e3 * c.mesh_eval->completeness.mean_m);
    if (c.tracked && c.tracked->ate)
      fmt::print("{:<26} tracked: ATE rmse {:.2f} cm, {:.1f} fps\n", c.config.name,
                 100 * c.tracked->ate->rmse_m, c.tracked_times.fps());
  }
}

void run_experiment_command(const ExperimentOptions& o) {
  if (o.run.threads > 0) set_thread_count(o.run.threads);
  const std::unique_ptr<DatasetReader> reader = open_dataset(o.run.data);
  const ExperimentParams params = experiment_params(o, *reader, "-experiment");

  fmt::print("hivox experiment {}: {} configurations, same-pose runs with poses '{}'\n",
             reader->info().source, params.configs.size(), params.poses.to_string());
  for (const ExperimentConfig& c : params.configs)
    fmt::print("  {:<26} {}\n", c.name, c.params.map.to_string());
  fmt::print("output: {}\n", params.out_dir.string());
  std::fflush(stdout);

  Stopwatch wall;
  const bool tty = isatty(fileno(stdout)) != 0;
  std::size_t total = 0;
  Stopwatch step_watch;
  ExperimentCallbacks callbacks;
  callbacks.on_step = [&](std::string_view step, int index, int count) {
    if (tty) fmt::print("\n");
    fmt::print("[{}/{}] {}  ({:.0f} s in)\n", index + 1, count, step, wall.elapsed_ms() / 1e3);
    std::fflush(stdout);
    step_watch = Stopwatch();
  };
  callbacks.run.on_start = [&](const Reconstruction&, std::size_t frames) { total = frames; };
  callbacks.run.on_frame = [&](std::size_t i, const FrameStats& s, const Reconstruction& rec,
                               const RgbdFrame&) {
    const std::size_t done = i + 1 - params.first_frame;
    if (!(tty || done % 100 == 0 || done == total)) return;
    fmt::print("{}  frame {}/{}  {:.1f} fps  blocks {}{}", tty ? "\r" : "", done, total,
               static_cast<double>(rec.frame_stats().size()) / (step_watch.elapsed_ms() / 1e3),
               s.blocks_total, tty ? "   " : "\n");
    std::fflush(stdout);
  };
  callbacks.run.stop_requested = [] { return stop_signal() != 0; };
  ExperimentResult result;
  {
    const StopOnSignals stop_on_signals;
    result = run_experiment(*reader, params, callbacks);
  }
  if (tty) fmt::print("\n");
  print_table(result);
  const fs::path dir = params.out_dir;
  if (!o.no_figures && draw_figures(dir))
    write_file_atomically(dir / "report.md", experiment_markdown(result, params));  // + figures
  fmt::print("\nreport: {}  ({:.0f} s)\n", (dir / "report.md").string(), wall.elapsed_ms() / 1e3);
  if (result.stopped) {
    log::error("the experiment was interrupted; what finished is in {}", dir.string());
    throw ExitStatus{interrupted_exit_status()};
  }
}

struct SdfErrorOptions {
  ExperimentOptions experiment;
  std::string fine, coarse, adaptive;
  std::vector<std::string> maps;
  bool json = false;
};

/// Prints the scores; `coarse` (an index into `maps`, or -1) is the reference of the ratio.
void print_sdf_error(const std::vector<MapSdfError>& maps, int64_t samples,
                     const std::string& reference, bool json, int coarse_index) {
  const double coarse =
      coarse_index >= 0 ? maps[static_cast<std::size_t>(coarse_index)].mean_abs_sdf_m : 0.0;
  if (json) {
    nlohmann::json j = {{"reference", reference}, {"samples", samples}};
    j["maps"] = nlohmann::json::array();
    for (const MapSdfError& m : maps)
      j["maps"].push_back({{"name", m.name},
                           {"mean_m", m.mean_abs_sdf_m},
                           {"median_m", m.median_abs_sdf_m},
                           {"rmse_m", m.rmse_m},
                           {"coverage", m.coverage},
                           {"ratio_to_coarsest", coarse > 0 ? m.mean_abs_sdf_m / coarse : 0.0},
                           {"points_per_level", m.points_per_level},
                           {"mean_per_level_m", m.mean_abs_sdf_per_level_m}});
    fmt::print("{}\n", j.dump(2));
    return;
  }
  fmt::print("sdf-error at {} points sampled on the mesh of {}\n", samples, reference);
  fmt::print("{:<26} {:>10} {:>10} {:>10} {:>7} {:>8}  {}\n", "map", "mean mm", "median mm",
             "rms mm", "ratio", "cover", "mean mm per level");
  for (const MapSdfError& m : maps) {
    std::vector<std::string> per;
    for (std::size_t l = 0; l < m.points_per_level.size(); ++l)
      per.push_back(
          fmt::format("{:.3f} ({})", 1e3 * m.mean_abs_sdf_per_level_m[l], m.points_per_level[l]));
    fmt::print("{:<26} {:>10.3f} {:>10.3f} {:>10.3f} {:>7.2f} {:>7.1f}%  {}\n", m.name,
               1e3 * m.mean_abs_sdf_m, 1e3 * m.median_abs_sdf_m, 1e3 * m.rmse_m,
               coarse > 0 ? m.mean_abs_sdf_m / coarse : 0.0, 100 * m.coverage,
               fmt::join(per, ", "));
  }
  if (coarse > 0) fmt::print("(ratio: to {})\n", maps[static_cast<std::size_t>(coarse_index)].name);
}

void run_sdf_error(SdfErrorOptions o) {
  if (!o.experiment.run.data.dataset.empty()) {
    if (!o.fine.empty() || !o.coarse.empty() || !o.adaptive.empty())
      fail(ErrorCode::InvalidArgument,
           "give either DATASET (reconstructed three ways) or saved maps (--fine, --coarse, "
           "--adaptive), not both");
    // The three same-pose runs of an experiment, without tracked runs or figures.
    o.experiment.tracked = "never";
    const std::unique_ptr<DatasetReader> reader = open_dataset(o.experiment.run.data);
    const ExperimentParams params = experiment_params(o.experiment, *reader, "-sdf-error");
    if (!o.json)
      fmt::print("reconstructing {} three ways (poses '{}') into {}\n", reader->info().source,
                 params.poses.to_string(), params.out_dir.string());
    std::fflush(stdout);
    ExperimentResult r;
    {
      const StopOnSignals stop_on_signals;
      ExperimentCallbacks callbacks;
      callbacks.run.stop_requested = [] { return stop_signal() != 0; };
      r = run_experiment(*reader, params, callbacks);
    }
    std::vector<MapSdfError> maps;
    for (const ConfigResult& c : r.configs) maps.push_back(c.sdf);
    print_sdf_error(maps, r.sdf_samples,
                    fmt::format("{} (the maps: {}/runs/*.hvx)", r.configs[0].config.name,
                                params.out_dir.string()),
                    o.json, r.coarsest_fixed);
    if (r.stopped) throw ExitStatus{interrupted_exit_status()};
    return;
  }
  if (o.fine.empty())
    fail(ErrorCode::InvalidArgument,
         "sdf-error needs DATASET, or saved maps: --fine MAP (the reference) and --coarse and/or "
         "--adaptive MAP");
  if (o.coarse.empty() && o.adaptive.empty() && o.maps.empty())
    fail(ErrorCode::InvalidArgument,
         "sdf-error: give --coarse, --adaptive or --map to compare "
         "with --fine {}",
         o.fine);
  std::vector<std::pair<std::string, std::string>> files = {{"fine", o.fine}};
  if (!o.coarse.empty()) files.push_back({"coarse", o.coarse});
  if (!o.adaptive.empty()) files.push_back({"adaptive", o.adaptive});
  for (const std::string& m : o.maps) files.push_back({fs::path(m).stem().string(), m});
  std::vector<LoadedMap> loaded;
  for (const auto& [name, path] : files) loaded.push_back(read_map_file(path));
  const TriangleMesh reference = extract_mesh(*loaded[0].map, o.experiment.run.mesh);
  if (reference.triangle_count() == 0)
    fail(ErrorCode::InvalidData, "{}: the map makes an empty mesh: no points to evaluate at",
         o.fine);
  std::vector<NamedMap> named;
  for (std::size_t i = 0; i < files.size(); ++i)
    named.push_back({fmt::format("{} ({})", files[i].first, files[i].second), loaded[i].map.get()});
  SdfErrorParams p;
  p.samples = o.experiment.samples;
  p.seed = o.experiment.seed;
  const SdfErrorResult r = evaluate_sdf_error(reference, named, p);
  print_sdf_error(r.maps, r.samples, o.fine, o.json, o.coarse.empty() ? -1 : 1);
}

}  // namespace

void add_experiment_command(CLI::App& app) {
  auto o = std::make_shared<ExperimentOptions>();
  CLI::App* cmd = app.add_subcommand(
      "experiment",
      "The paper's experiments on one dataset: the same frames and poses reconstructed as the "
      "fixed finest grid, the fixed coarsest grid and the adaptive hierarchy (and any --config), "
      "then blocks and saving (Table II, Fig. 6), sdf-error (Table I), time per stage, mesh "
      "accuracy against a reference mesh and the tracked runs' trajectory error when ground "
      "truth exists. Writes report.md, report.json, CSVs and figures (matplotlib) to --out.");
  add_dataset_options(cmd, o->run.data);
  add_fusion_options(cmd, o->run);
  o->poses_option = cmd->get_option("--poses");
  o->poses_option->description(
      "poses of the same-pose runs: 'gt', 'icp' (the first configuration tracks, the others take "
      "its trajectory) or a TUM file; default: gt when the dataset has ground truth, else icp");
  cmd->add_option("--frames", o->run.frames, "process N frames (0 = all)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--first-frame", o->run.first_frame, "start at this frame of the dataset")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--reference", o->reference,
                  "ground-truth mesh (.ply, .obj, .off) in the poses' world frame: mesh accuracy, "
                  "completeness and F-scores of every configuration");
  cmd->add_option("--config", o->configs,
                  "another configuration to compare: a config.json that `hivox reconstruct` "
                  "wrote (its settings on this dataset, with this experiment's poses and frames); "
                  "repeatable")
      ->type_name("FILE");
  cmd->add_option("--samples", o->samples, "sdf-error points on the fixed finest grid's mesh")
      ->capture_default_str();
  cmd->add_option("--mesh-samples", o->mesh_samples,
                  "points sampled on each mesh and on the reference for --reference")
      ->capture_default_str();
  cmd->add_option("--seed", o->seed, "seed of the point sampling")->capture_default_str();
  cmd->add_option("--tracked", o->tracked,
                  "also run each configuration with ICP tracking (ATE, the whole loop's speed): "
                  "auto (when the same-pose runs use ground truth), always, never")
      ->check(CLI::IsMember({"auto", "always", "never"}))
      ->capture_default_str();
  cmd->add_option("--out", o->out, "output folder (default out/<dataset name>-experiment)")
      ->type_name("DIR");
  cmd->add_flag("--overwrite", o->overwrite, "replace an output folder that holds files");
  cmd->add_flag("--no-figures", o->no_figures, "do not run the plotting script");
  cmd->footer(
      "The options of `hivox reconstruct` set the adaptive configuration; the fixed grids take "
      "its finest and coarsest voxel sizes with one level.\n\n"
      "Examples:\n"
      "  hivox experiment ../shared/data/tum_fr1_rpy\n"
      "  hivox experiment out/replica_render --reference "
      "../shared/data/replica_office0/office0_mesh_decimated50k.ply\n"
      "  hivox experiment 'synthetic:desk?frames=100&noise=none' --samples 200000 --out "
      "out/desk-exp\n"
      "  hivox experiment DATASET --config out/run-a/config.json --config out/run-b/config.json");
  cmd->callback([o] { run_experiment_command(*o); });
}

void add_sdf_error_command(CLI::App* eval) {
  auto o = std::make_shared<SdfErrorOptions>();
  CLI::App* cmd = eval->add_subcommand(
      "sdf-error",
      "The paper's Table I score: points sampled uniformly by area on the fixed finest grid's "
      "mesh, and the mean |SDF| of the fixed coarsest grid and the adaptive map there (mm). From "
      "DATASET (reconstructed three ways with the same poses; the maps are kept) or from saved "
      "maps.");
  add_dataset_options(cmd, o->experiment.run.data);
  cmd->get_option("DATASET")->required(false);
  add_fusion_options(cmd, o->experiment.run);
  o->experiment.poses_option = cmd->get_option("--poses");
  cmd->add_option("--frames", o->experiment.run.frames, "process N frames (0 = all)")
      ->capture_default_str();
  cmd->add_option("--fine", o->fine, "saved map of the fixed finest grid: the reference")
      ->type_name("MAP");
  cmd->add_option("--coarse", o->coarse, "saved map of the fixed coarsest grid")->type_name("MAP");
  cmd->add_option("--adaptive", o->adaptive, "saved map of the adaptive hierarchy")
      ->type_name("MAP");
  cmd->add_option("--map", o->maps, "any other saved map to score (repeatable)")->type_name("MAP");
  cmd->add_option("--samples", o->experiment.samples, "points on the reference mesh (paper: 20 M)")
      ->capture_default_str();
  cmd->add_option("--seed", o->experiment.seed, "seed of the sampling")->capture_default_str();
  cmd->add_option("--out", o->experiment.out,
                  "with DATASET: where the runs and maps go (default out/<name>-sdf-error)")
      ->type_name("DIR");
  cmd->add_flag("--overwrite", o->experiment.overwrite,
                "replace an output folder that holds files");
  cmd->add_flag("--json", o->json, "print one JSON object instead of the table");
  cmd->footer(
      "Examples:\n"
      "  hivox eval sdf-error 'synthetic:desk?frames=100&noise=none'\n"
      "  hivox eval sdf-error ../shared/data/tum_fr1_rpy --frames 300 --out out/rpy-sdf\n"
      "  hivox eval sdf-error --fine out/rpy-sdf/runs/fixed-2mm.hvx --coarse "
      "out/rpy-sdf/runs/fixed-8mm.hvx --adaptive out/rpy-sdf/runs/adaptive.hvx --samples "
      "20000000");
  cmd->callback([o] { run_sdf_error(*o); });
}

}  // namespace hivox::cli

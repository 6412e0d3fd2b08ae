// `hivox eval ate --gt FILE --est FILE`: absolute trajectory error of an estimated trajectory
// against ground truth, with the numbers of the TUM RGB-D benchmark's evaluate_ate.py.

#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "hivox/core/error.h"
#include "hivox/core/log.h"
#include "hivox/core/timer.h"
#include "hivox/eval/mesh_eval.h"
#include "hivox/eval/trajectory_eval.h"
#include "hivox/io/mesh_file.h"
#include "hivox/io/trajectory_io.h"

namespace hivox::cli {

namespace {

struct AteOptions {
  std::string gt_path;
  std::string est_path;
  double max_dt_s = AteParams{}.max_dt_s;
  bool no_align = false;
  bool json = false;
};

std::vector<StampedPose> read_poses(const std::string& path) {
  std::vector<StampedPose> poses = read_tum_trajectory(path);
  if (poses.empty())
    fail(ErrorCode::InvalidData, "{}: no poses (only comments or blank lines)", path);
  const std::string order = timestamp_order_problems(poses);
  if (!order.empty())
    log::warn("{}: {}; poses are associated by nearest timestamp all the same", path, order);
  return poses;
}

void run_ate(const AteOptions& o) {
  if (!std::isfinite(o.max_dt_s) || o.max_dt_s <= 0)
    fail(ErrorCode::InvalidArgument, "--max-dt must be > 0 seconds, got {}", o.max_dt_s);
  AteParams params;
  params.max_dt_s = o.max_dt_s;
  params.align = !o.no_align;
  const std::vector<StampedPose> gt = read_poses(o.gt_path);
  const std::vector<StampedPose> est = read_poses(o.est_path);
  AteResult r;
  try {
    r = evaluate_ate(gt, est, params);
  } catch (const Error& e) {
    fail(e.code(), "{} against {}: {}", o.est_path, o.gt_path, e.what());
  }

  if (o.json) {
    const nlohmann::json j = {
        {"rmse_m", r.rmse_m},     {"mean_m", r.mean_m},      {"median_m", r.median_m},
        {"std_m", r.std_m},       {"min_m", r.min_m},        {"max_m", r.max_m},
        {"matched", r.matched},   {"est_poses", est.size()}, {"gt_poses", gt.size()},
        {"max_dt_s", o.max_dt_s}, {"aligned", params.align},
    };
    fmt::print("{}\n", j.dump(2));
    return;
  }
  fmt::print("hivox eval ate: {} against ground truth {}\n", o.est_path, o.gt_path);
  fmt::print("settings:  {}\n", params.to_string());
  fmt::print("matched:   {} of {} estimated poses ({} ground-truth poses)\n", r.matched, est.size(),
             gt.size());
  if (params.align)
    fmt::print("alignment: rotation {:.3f} deg, translation {:.4f} m\n",
               rotation_angle_rad(r.T_gt_est) * 180.0 / std::numbers::pi,
               r.T_gt_est.translation().norm());
  const auto row = [](const char* name, double v_m) {
    fmt::print("  {:<7} {:10.6f} m  ({:.2f} cm)\n", name, v_m, v_m * 100.0);
  };
  fmt::print("ATE (translation error after {}):\n", params.align ? "alignment" : "no alignment");
  row("rmse", r.rmse_m);
  row("mean", r.mean_m);
  row("median", r.median_m);
  row("std", r.std_m);
  row("min", r.min_m);
  row("max", r.max_m);
}

struct MeshOptions {
  std::string reference, mesh;
  MeshEvalParams params;
  bool json = false;
};

void run_mesh_eval(const MeshOptions& o) {
  o.params.validate();
  Stopwatch watch;
  const TriangleMesh reference = read_mesh(o.reference);
  const TriangleMesh mesh = read_mesh(o.mesh);
  MeshEvalResult r;
  try {
    r = evaluate_mesh(mesh, reference, o.params);
  } catch (const Error& e) {
    fail(e.code(), "{} against {}: {}", o.mesh, o.reference, e.what());
  }
  const double seconds = watch.elapsed_ms() / 1e3;
  const auto stats = [](const DistanceStats& d) {
    return nlohmann::json{
        {"mean_m", d.mean_m}, {"median_m", d.median_m}, {"rmse_m", d.rmse_m}, {"max_m", d.max_m}};
  };
  if (o.json) {
    nlohmann::json f = nlohmann::json::array();
    for (const FScore& s : r.fscores)
      f.push_back({{"threshold_m", s.threshold_m},
                   {"precision", s.precision},
                   {"recall", s.recall},
                   {"fscore", s.fscore}});
    const nlohmann::json j = {{"mesh", o.mesh},
                              {"reference", o.reference},
                              {"accuracy", stats(r.accuracy)},
                              {"completeness", stats(r.completeness)},
                              {"chamfer_m", r.chamfer_m},
                              {"fscores", f},
                              {"samples", r.mesh_samples},
                              {"seed", o.params.seed},
                              {"seconds", seconds}};
    fmt::print("{}\n", j.dump(2));
    return;
  }
  fmt::print("hivox eval mesh: {} against the reference {}\n", o.mesh, o.reference);
  fmt::print("meshes:  {} triangles against {}; {} points sampled on each (seed {})\n",
             mesh.triangle_count(), reference.triangle_count(), r.mesh_samples, o.params.seed);
  const auto mm = [](double m) { return fmt::format("{:8.3f} mm", m * 1e3); };
  fmt::print("{:<28} {:>11} {:>11} {:>11} {:>11}\n", "distance to the other surface", "mean",
             "median", "rmse", "max");
  for (const auto& [name, d] : {std::pair{"accuracy (mesh -> ref)", r.accuracy},
                                std::pair{"completeness (ref -> mesh)", r.completeness}})
    fmt::print("{:<28} {:>11} {:>11} {:>11} {:>11}\n", name, mm(d.mean_m), mm(d.median_m),
               mm(d.rmse_m), mm(d.max_m));
  fmt::print("chamfer (mean of the two means): {}\n", mm(r.chamfer_m));
  for (const FScore& s : r.fscores)
    fmt::print("within {:g} mm: precision {:.1f} %, recall {:.1f} %, F-score {:.1f} %\n",
               s.threshold_m * 1e3, 100 * s.precision, 100 * s.recall, 100 * s.fscore);
  fmt::print("({:.1f} s)\n", seconds);
}

}  // namespace

void add_eval_command(CLI::App& app) {
  CLI::App* eval = app.add_subcommand("eval", "Evaluate results against ground truth.");
  eval->require_subcommand(1);

  auto o = std::make_shared<AteOptions>();
  CLI::App* ate = eval->add_subcommand(
      "ate",
      "Absolute trajectory error (ATE) of an estimated trajectory against ground truth, as the "
      "TUM RGB-D benchmark's evaluate_ate.py computes it: poses are matched by timestamp, the "
      "estimate is rigidly aligned to the ground truth (rotation + translation, no scale), and "
      "the error is the distance between matched positions.");
  ate->footer(
      "Both files are TUM trajectories: 't tx ty tz qx qy qz qw' per line, camera-to-world\n"
      "(hivox reconstruct writes trajectory.txt in this format; TUM sequences ship\n"
      "groundtruth.txt). Each estimated pose is matched to the nearest unused ground-truth pose\n"
      "with |dt| < --max-dt, closest pairs first (TUM's associate.py, offset 0).\n"
      "\n"
      "Examples:\n"
      "  hivox eval ate --gt ../shared/data/tum_fr1_rpy/groundtruth.txt --est "
      "out/fr1/trajectory.txt\n"
      "  hivox eval ate --gt gt.txt --est est.txt --json");
  ate->add_option("--gt", o->gt_path, "Ground-truth trajectory (TUM format)")->required();
  ate->add_option("--est", o->est_path, "Estimated trajectory (TUM format)")->required();
  ate->add_option("--max-dt", o->max_dt_s,
                  "Largest timestamp difference of a matched pair, seconds (TUM: 0.02)")
      ->capture_default_str();
  ate->add_flag("--no-align", o->no_align,
                "Compare positions as they are, without the rigid alignment");
  ate->add_flag("--json", o->json,
                "Print one JSON object (rmse_m, mean_m, median_m, std_m, min_m, max_m, matched, "
                "...) instead of the table");
  ate->callback([o] { run_ate(*o); });

  auto m = std::make_shared<MeshOptions>();
  CLI::App* mesh = eval->add_subcommand(
      "mesh",
      "A mesh against a reference mesh: points sampled uniformly by area on each, and each "
      "point's distance to the other mesh's nearest triangle. Accuracy: the mesh's points to the "
      "reference; completeness: the reference's points to the mesh; Chamfer: the mean of the two "
      "means; precision, recall and F-score: the points within each threshold.");
  mesh->add_option("--reference", m->reference,
                   "the reference (ground-truth) mesh: .ply, .obj, .off")
      ->required();
  mesh->add_option("--mesh", m->mesh, "the mesh to evaluate: .ply, .obj, .off")->required();
  mesh->add_option("--samples", m->params.samples, "points sampled on each mesh")
      ->capture_default_str();
  mesh->add_option("--thresholds", m->params.thresholds_m,
                   "distances for precision, recall and F-score, metres")
      ->delimiter(',')
      ->capture_default_str();
  mesh->add_option("--seed", m->params.seed, "seed of the sampling")->capture_default_str();
  mesh->add_flag("--json", m->json, "print one JSON object instead of the table");
  mesh->footer(
      "Examples:\n"
      "  hivox eval mesh --reference ../shared/data/replica_office0/mesh.ply --mesh "
      "out/office/mesh.ply\n"
      "  hivox eval mesh --reference ref.obj --mesh mesh.ply --thresholds 0.002,0.005,0.01 --json");
  mesh->callback([m] { run_mesh_eval(*m); });

  add_sdf_error_command(eval);
}

}  // namespace hivox::cli

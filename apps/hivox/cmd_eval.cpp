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
#include "hivox/eval/trajectory_eval.h"
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
}

}  // namespace hivox::cli

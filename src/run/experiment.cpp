#include "hivox/run/experiment.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "hivox/core/error.h"
#include "hivox/core/timer.h"
#include "hivox/io/atomic_file.h"
#include "hivox/io/mesh_file.h"
#include "hivox/output/output_folder.h"
#include "hivox/output/renders.h"

namespace hivox {

namespace fs = std::filesystem;

namespace {

std::string mm_slug(float voxel_m) {
  std::string s = fmt::format("{:g}", voxel_m * 1000.0f);
  std::replace(s.begin(), s.end(), '.', 'p');
  return s + "mm";
}

bool valid_slug(const std::string& s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-';
  });
}

/// A run of configuration `cfg` with the experiment's frames, mesh settings and bad-frame rule.
RunParams config_run(const ExperimentParams& params, const ExperimentConfig& cfg,
                     const PoseSpec& poses, const fs::path& out_dir) {
  RunParams rp;
  rp.reconstruction = cfg.params;
  rp.poses = poses;
  rp.first_frame = params.first_frame;
  rp.max_frames = params.max_frames;
  rp.mesh = params.mesh;
  rp.on_bad_frame = params.on_bad_frame;
  rp.out_dir = out_dir;
  return rp;
}

/// The coarsest single-level configuration, the reference of the sdf-error ratio (paper Table I
/// gives the adaptive map's error beside the coarse grid's); -1 when there is none.
int coarsest_fixed(const std::vector<ConfigResult>& configs) {
  int best = -1;
  for (std::size_t i = 0; i < configs.size(); ++i) {
    const MapParams& m = configs[i].config.params.map;
    if (m.levels == 1 &&
        (best < 0 ||
         m.voxel_size_m > configs[static_cast<std::size_t>(best)].config.params.map.voxel_size_m))
      best = static_cast<int>(i);
  }
  return best;
}

/// The camera of the overview renders (as the run's own overview).
const PinholeCamera kOverviewCamera{600.0f, 600.0f, 479.5f, 359.5f, 960, 720};

/// Surface detail in a render: the pixels whose normal turns by more than 30 degrees to the
/// right or below neighbour (edges, corners, small objects).
int64_t detail_pixels(const RaycastResult& r) {
  int64_t n = 0;
  const float cos30 = 0.866f;
  for (int y = 0; y + 1 < r.depth_m.height(); ++y)
    for (int x = 0; x + 1 < r.depth_m.width(); ++x) {
      if (!r.hit(x, y) || !r.hit(x + 1, y) || !r.hit(x, y + 1)) continue;
      const Vec3f& c = r.normals_w(x, y);
      if (dot(c, r.normals_w(x + 1, y)) < cos30 || dot(c, r.normals_w(x, y + 1)) < cos30) ++n;
    }
  return n;
}

/// Which points of a reference surface the sequence observed: those that some frame (of up to
/// `max_views` spread over the run) sees unoccluded -- projected inside the image onto a valid
/// depth within 2 cm (or 3 % of the depth) of the point's own. Frames without a ground-truth
/// pose are passed over.
class ObservedSurface {
 public:
  ObservedSurface(DatasetReader& reader, std::size_t first, std::size_t count,
                  std::size_t max_views = 60)
      : camera_(reader.info().rig.depth_camera) {
    const std::size_t end = std::min(reader.size(), count > 0 ? first + count : reader.size());
    const std::size_t step = std::max<std::size_t>(1, (end - first) / max_views);
    for (std::size_t i = first; i < end; i += step) {
      RgbdFrame frame;
      try {
        frame = reader.read(i);
      } catch (const Error&) {
        continue;  // a bad frame is the run's business; it only gives no view here
      }
      if (!frame.T_wc_gt) continue;
      views_.push_back({std::move(frame.depth_m), frame.T_wc_gt->inverse()});
    }
  }
  bool empty() const { return views_.empty(); }
  std::size_t views() const { return views_.size(); }

  bool operator()(const Vec3f& p) const {
    const Eigen::Vector3d pw(p.x, p.y, p.z);
    for (const View& v : views_) {
      const Eigen::Vector3d c = v.T_cw * pw;
      if (c.z() <= 0.0) continue;
      const long u = std::lround(camera_.fx * c.x() / c.z() + camera_.cx);
      const long w = std::lround(camera_.fy * c.y() / c.z() + camera_.cy);
      if (u < 0 || w < 0 || u >= camera_.width || w >= camera_.height) continue;
      const float d = v.depth_m(static_cast<int>(u), static_cast<int>(w));
      if (d > 0.0f && std::abs(d - c.z()) < std::max(0.02, 0.03 * c.z())) return true;
    }
    return false;
  }

 private:
  struct View {
    DepthImage depth_m;
    Pose T_cw;
  };
  PinholeCamera camera_;
  std::vector<View> views_;
};

}  // namespace

std::vector<ExperimentConfig> hierarchy_configs(const ReconstructionParams& adaptive) {
  const int levels = adaptive.map.levels;
  if (levels < 2)
    fail(ErrorCode::InvalidArgument,
         "an experiment compares the hierarchy with fixed grids: it needs --levels >= 2, got {}",
         levels);
  ReconstructionParams fine = adaptive, coarse = adaptive;
  fine.map.levels = 1;
  // The fixed finest grid needs several times the adaptive map's blocks (the paper's saving):
  // its tables are 4x as large, so that a full pool never decides the comparison. Memory is used
  // only as blocks are allocated.
  fine.map.max_blocks = adaptive.map.max_blocks * 4;
  fine.map.buckets_per_level = adaptive.map.buckets_per_level * 4;
  fine.map.excess_per_level = adaptive.map.excess_per_level * 4;
  coarse.map.levels = 1;
  coarse.map.voxel_size_m = adaptive.map.voxel_size_at(levels - 1);
  const auto mm = [](float m) { return fmt::format("{:g} mm", m * 1000.0f); };
  return {
      {"fixed " + mm(fine.map.voxel_size_m), "fixed-" + mm_slug(fine.map.voxel_size_m), fine},
      {"fixed " + mm(coarse.map.voxel_size_m), "fixed-" + mm_slug(coarse.map.voxel_size_m), coarse},
      {fmt::format("adaptive {}-{}", mm(adaptive.map.voxel_size_m), mm(coarse.map.voxel_size_m)),
       "adaptive", adaptive},
  };
}

void ExperimentParams::validate() const {
  if (configs.empty()) fail(ErrorCode::InvalidArgument, "experiment: no configuration to run");
  for (std::size_t i = 0; i < configs.size(); ++i) {
    const ExperimentConfig& c = configs[i];
    if (!valid_slug(c.slug))
      fail(ErrorCode::InvalidArgument,
           "experiment: configuration '{}' has the folder name '{}' (use a-z, 0-9 and -)", c.name,
           c.slug);
    for (std::size_t j = 0; j < i; ++j)
      if (configs[j].slug == c.slug)
        fail(ErrorCode::InvalidArgument,
             "experiment: two configurations have the folder name '{}' ('{}', '{}')", c.slug,
             configs[j].name, c.name);
    c.params.validate();
  }
  if (out_dir.empty()) fail(ErrorCode::InvalidArgument, "experiment: an output folder is needed");
  sdf.validate();
  mesh_eval.validate();
  mesh.validate();
  if (csv_points < 0)
    fail(ErrorCode::InvalidArgument, "experiment: csv_points must be >= 0, got {}", csv_points);
}

ExperimentResult run_experiment(DatasetReader& reader, const ExperimentParams& params,
                                const ExperimentCallbacks& callbacks) {
  params.validate();
  if (!params.reference_mesh.empty() && !fs::exists(params.reference_mesh))
    fail(ErrorCode::Io, "{}: no such reference mesh", params.reference_mesh.string());
  const bool tracked = params.tracked == TrackedRuns::Always ||
                       (params.tracked == TrackedRuns::Auto && reader.info().has_ground_truth &&
                        params.poses.source == PoseSource::GroundTruth);
  Stopwatch watch;
  OutputFolder folder(params.out_dir, params.overwrite);
  const fs::path dir = folder.dir();
  fs::create_directories(dir / "runs");
  fs::create_directories(dir / "renders");

  ExperimentResult result;
  result.dataset = reader.info().source;
  result.poses = params.poses.to_string();
  const std::size_t n = params.configs.size();
  const int steps = static_cast<int>(n * (tracked ? 2 : 1));
  int step = 0;
  const auto begin_step = [&](const std::string& what) {
    if (callbacks.on_step) callbacks.on_step(what, step, steps);
    ++step;
  };

  // With a reference mesh: completeness over the part of it the frames saw (where the poses
  // are known).
  std::optional<TriangleMesh> reference;
  std::optional<ObservedSurface> observed;
  MeshEvalParams mesh_eval = params.mesh_eval;
  if (!params.reference_mesh.empty()) {
    reference = read_mesh(params.reference_mesh);
    observed.emplace(reader, params.first_frame, params.max_frames);
    if (!observed->empty())
      mesh_eval.reference_filter = [&observed](const Vec3f& p) { return (*observed)(p); };
    result.reference_observed_views = observed->views();
  }
  std::vector<Vec3f> points;
  std::vector<std::vector<float>> per_point(n);
  std::vector<std::vector<FrameStats>> frames(n);
  Pose overview = Pose::Identity(), close = Pose::Identity();
  float overview_depth = 0.0f;
  const PinholeCamera close_camera = reader.info().rig.depth_camera;

  for (std::size_t i = 0; i < n && !result.stopped; ++i) {
    const ExperimentConfig& cfg = params.configs[i];
    begin_step(fmt::format("{}: same poses ({}){}", cfg.name,
                           i > 0 && params.poses.source == PoseSource::Icp
                               ? "the first configuration's tracked trajectory"
                               : params.poses.to_string(),
                           reference ? ", then its mesh against the reference" : ""));
    const PoseSpec poses =
        i > 0 && params.poses.source == PoseSource::Icp
            ? PoseSpec{PoseSource::File, dir / "runs" / params.configs[0].slug / "trajectory.txt"}
            : params.poses;
    RunParams rp = config_run(params, cfg, poses, dir / "runs" / cfg.slug);
    rp.map_out = dir / "runs" / (cfg.slug + ".hvx");
    RunResult run = run_reconstruction(reader, rp, callbacks.run);
    if (run.summary.end == RunEnd::StopRequested) result.stopped = true;
    if (run.summary.end == RunEnd::BadFrame)
      fail(ErrorCode::InvalidData, "experiment: {} stopped at a bad frame: {}", cfg.name,
           run.summary.end_reason);
    const Reconstruction& rec = *run.reconstruction;

    ConfigResult c;
    c.config = cfg;
    c.run = run.summary;
    c.times = mean_stage_times(rec.frame_stats());
    c.blocks = rec.map().blocks_in_use();
    c.peak_blocks = rec.peak_blocks();
    c.blocks_per_level = rec.map().blocks_per_level();
    c.memory_mib = static_cast<double>(rec.map().memory_bytes()) / (1024.0 * 1024.0);
    c.dropped_blocks = rec.map().dropped_blocks();
    frames[i] = rec.frame_stats();
    // The run's mesh, read once: the sdf-error's points (the first configuration) and the
    // comparison with the reference.
    const TriangleMesh mesh = read_mesh(dir / "runs" / cfg.slug / "mesh.ply");
    if (reference && mesh.triangle_count() > 0)
      c.mesh_eval = evaluate_mesh(mesh, *reference, mesh_eval);
    if (i == 0) {
      result.frames = rec.frame_stats().size();
      if (mesh.triangle_count() == 0)
        fail(ErrorCode::InvalidData,
             "experiment: the first configuration ({}) made an empty mesh: no sdf-error "
             "reference (are the poses and depth right?)",
             cfg.name);
      points = sample_surface(mesh, params.sdf.samples, params.sdf.seed);
      result.sdf_samples = static_cast<int64_t>(points.size());
      overview = rec.overview_pose(kOverviewCamera, &overview_depth);
      // The close-up: of 16 poses spread over the trajectory, the one that sees most detail.
      int64_t best = -1;
      const std::vector<StampedPose>& path = rec.trajectory();
      for (std::size_t k = 0; k < 16; ++k) {
        const Pose& pose = path[k * path.size() / 16].T_wc;
        const int64_t d = detail_pixels(run.reconstruction->render(close_camera, pose));
        if (d > best) {
          best = d;
          close = pose;
        }
      }
    }
    c.sdf = score_map(rec.map(), points, params.sdf.min_weight, &per_point[i]);
    c.sdf.name = cfg.name;
    for (const auto& [camera, pose, depth, name] :
         {std::tuple{kOverviewCamera, overview, overview_depth, "overview"},
          std::tuple{close_camera, close, 0.0f, "close"}})
      for (const fs::path& f :
           write_renders(run.reconstruction->render(camera, pose, depth), cfg.params.map,
                         dir / "renders", fmt::format("{}_{}_", cfg.slug, name)))
        result.files.push_back(folder.final_path(f));
    result.configs.push_back(std::move(c));
  }

  for (std::size_t i = 0; tracked && i < result.configs.size() && !result.stopped; ++i) {
    ConfigResult& c = result.configs[i];
    begin_step(fmt::format("{}: tracked (ICP)", c.config.name));
    RunResult run = run_reconstruction(reader,
                                       config_run(params, c.config, PoseSpec{PoseSource::Icp, {}},
                                                  dir / "runs" / (c.config.slug + "-tracked")),
                                       callbacks.run);
    if (run.summary.end == RunEnd::StopRequested) result.stopped = true;
    c.tracked = run.summary;
    c.tracked_times = mean_stage_times(run.reconstruction->frame_stats());
  }

  const double first_blocks =
      result.configs.empty() ? 0.0 : static_cast<double>(result.configs[0].blocks);
  result.coarsest_fixed = coarsest_fixed(result.configs);
  const double coarse_sdf =
      result.coarsest_fixed >= 0
          ? result.configs[static_cast<std::size_t>(result.coarsest_fixed)].sdf.mean_abs_sdf_m
          : 0.0;
  for (ConfigResult& c : result.configs) {
    c.block_saving = first_blocks > 0 ? 1.0 - static_cast<double>(c.blocks) / first_blocks : 0.0;
    c.sdf_ratio = coarse_sdf > 0 ? c.sdf.mean_abs_sdf_m / coarse_sdf : 0.0;
  }

  // blocks.csv: one row per frame, per configuration the blocks in all and per level.
  {
    std::string csv = "frame";
    for (const ConfigResult& c : result.configs) {
      csv += fmt::format(",{}", c.config.slug);
      for (std::size_t l = 0; l < c.blocks_per_level.size(); ++l)
        csv += fmt::format(",{}_level{}", c.config.slug, l);
    }
    csv += '\n';
    std::size_t rows = 0;
    for (std::size_t i = 0; i < result.configs.size(); ++i) rows = std::max(rows, frames[i].size());
    for (std::size_t r = 0; r < rows; ++r) {
      csv += fmt::format("{}", r < frames[0].size() ? frames[0][r].index : r);
      for (std::size_t i = 0; i < result.configs.size(); ++i) {
        const std::size_t levels = result.configs[i].blocks_per_level.size();
        if (r < frames[i].size()) {
          const FrameStats& f = frames[i][r];
          csv += fmt::format(",{}", f.blocks_total);
          for (std::size_t l = 0; l < levels; ++l)
            csv += fmt::format(",{}", l < f.blocks_per_level.size() ? f.blocks_per_level[l] : 0);
        } else {
          csv += std::string(levels + 1, ',');
        }
      }
      csv += '\n';
    }
    write_file_atomically(dir / "blocks.csv", csv);
    result.files.push_back(folder.final_path(dir / "blocks.csv"));
  }
  // sdf_points.csv: an even subsample of the points with each map's |SDF| (mm; empty: none).
  {
    std::string csv = "x,y,z";
    for (const ConfigResult& c : result.configs) csv += "," + c.config.slug + "_mm";
    csv += '\n';
    const std::size_t every =
        params.csv_points > 0
            ? std::max<std::size_t>(1, points.size() / static_cast<std::size_t>(params.csv_points))
            : points.size() + 1;
    for (std::size_t p = 0; p < points.size(); p += every) {
      csv += fmt::format("{:.5f},{:.5f},{:.5f}", points[p].x, points[p].y, points[p].z);
      for (std::size_t i = 0; i < result.configs.size(); ++i) {
        const float e = per_point[i][p];
        csv += e >= 0.0f ? fmt::format(",{:.4f}", e * 1e3f) : std::string(",");
      }
      csv += '\n';
    }
    write_file_atomically(dir / "sdf_points.csv", csv);
    result.files.push_back(folder.final_path(dir / "sdf_points.csv"));
  }
  result.wall_s = watch.elapsed_ms() / 1e3;
  // The reports name the final folder.
  ExperimentParams final_params = params;
  final_params.out_dir = dir;
  write_file_atomically(dir / "report.json", experiment_json(result, final_params));
  write_file_atomically(dir / "report.md", experiment_markdown(result, final_params));
  result.files.push_back(folder.final_path(dir / "report.json"));
  result.files.push_back(folder.final_path(dir / "report.md"));
  folder.commit();
  return result;
}

}  // namespace hivox

// The commands on saved maps (`.hvx`, written by `hivox reconstruct --save-map`): `mesh`, `render`
// and `export`, and `info` on a map file (the dataset's `info` lives in cmd_info.cpp).

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "commands.h"
#include "hivox/core/error.h"
#include "hivox/core/log.h"
#include "hivox/core/threads.h"
#include "hivox/core/timer.h"
#include "hivox/io/map_file.h"
#include "hivox/io/npz.h"
#include "hivox/io/obj.h"
#include "hivox/io/ply.h"
#include "hivox/io/trajectory_io.h"
#include "hivox/mesh/extract_mesh.h"
#include "hivox/output/renders.h"
#include "hivox/raycast/render.h"
#include "hivox/run/devices.h"
#include "hivox/run/runner.h"

namespace hivox::cli {

namespace {

namespace fs = std::filesystem;

/// The camera renders take when neither --camera nor the map names one (a Kinect's).
constexpr PinholeCamera kDefaultCamera{525.0f, 525.0f, 319.5f, 239.5f, 640, 480};
constexpr const char* kDeviceHelp =
    "where the map is meshed and rendered: cpu, or cuda / cuda:N (builds with the CUDA loop; "
    "the map is copied there once)";

/// Numbers separated by commas or spaces, exactly `n` of them; errors name `option`.
std::vector<double> parse_numbers(const std::string& text, std::size_t n, const char* option,
                                  const char* meaning) {
  std::vector<double> out;
  std::string token;
  auto flush = [&] {
    if (token.empty()) return;
    std::size_t used = 0;
    double v = 0;
    try {
      v = std::stod(token, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != token.size() || !std::isfinite(v))
      fail(ErrorCode::InvalidArgument, "{} '{}': '{}' is not a number (expected {})", option, text,
           token, meaning);
    out.push_back(v);
    token.clear();
  };
  for (const char c : text) {
    if (c == ',' || c == ' ')
      flush();
    else
      token += c;
  }
  flush();
  if (out.size() != n)
    fail(ErrorCode::InvalidArgument, "{} '{}': {} numbers, expected {} ({})", option, text,
         out.size(), n, meaning);
  return out;
}

std::string mib(int64_t bytes) {
  return fmt::format("{:.1f} MiB", static_cast<double>(bytes) / (1 << 20));
}

/// `loaded`'s map behind a Reconstruction on `device`, seen through `camera`: its meshes and
/// renders are made there (elsewhere than the CPU the map crosses the bus once, said unless
/// `quiet`).
std::unique_ptr<Reconstruction> on_device(LoadedMap loaded, const Device& device,
                                          const PinholeCamera& camera, bool quiet) {
  ReconstructionParams p;
  p.device = device;
  p.map = loaded.map->params();
  p.fusion = loaded.info.fusion;
  Stopwatch watch;
  std::unique_ptr<Reconstruction> rec = make_reconstruction(
      p, CameraRig::registered(camera), std::move(loaded.map), loaded.info.session);
  if (!quiet && !device.is_cpu()) {
    const std::optional<DeviceInfo> d = describe_device(device);
    fmt::print("on {} ({}) in {:.2f} s\n", device.to_string(), d ? d->to_string() : "",
               watch.elapsed_ms() / 1e3);
  }
  return rec;
}

LoadedMap load(const std::string& path, bool quiet, double* seconds = nullptr) {
  Stopwatch watch;
  LoadedMap loaded = read_map_file(path);
  if (seconds) *seconds = watch.elapsed_ms() / 1e3;
  if (!quiet)
    fmt::print("{}: {} blocks ({}) loaded in {:.2f} s\n", path, loaded.map->blocks_in_use(),
               fmt::join(loaded.map->blocks_per_level(), "/"), watch.elapsed_ms() / 1e3);
  return loaded;
}

// ---- info -------------------------------------------------------------------------------------

void print_map_info(const std::string& path) {
  double load_s = 0;
  const LoadedMap loaded = load(path, true, &load_s);
  const MapFileInfo& info = loaded.info;
  const VoxelBlockMap& map = *loaded.map;
  const MapParams& p = map.params();
  fmt::print("map file: {} ({}, format version {}, written by hivox {})\n", path,
             mib(info.file_bytes), info.format_version, info.library_version);
  fmt::print("loaded in {:.2f} s\n", load_s);
  fmt::print("levels: {}, truncation {:.1f} mm, colour {}\n", p.levels, p.truncation_m * 1000.0f,
             p.store_color ? "stored" : "not stored");
  const std::vector<int64_t> blocks = map.blocks_per_level();
  for (int l = 0; l < p.levels; ++l)
    fmt::print("  level {}: voxel {:.1f} mm, {} blocks, {} split entries\n", l,
               p.voxel_size_at(l) * 1000.0f, blocks[static_cast<std::size_t>(l)],
               info.splits_per_level[static_cast<std::size_t>(l)]);
  const int64_t voxel_bytes = map.blocks_in_use() * kBlockVoxels * p.bytes_per_voxel();
  fmt::print("memory: {} of voxels ({} blocks x {} B), {} with the tables as loaded\n",
             mib(voxel_bytes), map.blocks_in_use(), kBlockVoxels * p.bytes_per_voxel(),
             mib(map.memory_bytes()));
  Vec3f lo{std::numeric_limits<float>::max(), std::numeric_limits<float>::max(),
           std::numeric_limits<float>::max()};
  Vec3f hi{-lo.x, -lo.y, -lo.z};
  for (const BlockRef& b : map.allocated_blocks()) {
    const float s = p.block_size_at(b.level);
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], static_cast<float>(b.pos[a]) * s);
      hi[a] = std::max(hi[a], static_cast<float>(b.pos[a] + 1) * s);
    }
  }
  if (map.blocks_in_use() > 0)
    fmt::print(
        "bounding box: [{:.3f}, {:.3f}, {:.3f}] .. [{:.3f}, {:.3f}, {:.3f}] m ({:.2f} x "
        "{:.2f} x {:.2f} m)\n",
        lo.x, lo.y, lo.z, hi.x, hi.y, hi.z, hi.x - lo.x, hi.y - lo.y, hi.z - lo.z);
  else
    fmt::print("bounding box: none (no blocks)\n");
  fmt::print("fusion: {}\n", info.fusion.to_string());
  const MapSession& s = info.session;
  fmt::print("frames fused: {}\n", s.frames_fused);
  if (s.last_pose) {
    const std::array<double, 7> t = to_tum(*s.last_pose);
    fmt::print("last pose (tx ty tz qx qy qz qw): {:.4f}\n", fmt::join(t, " "));
  }
  if (s.camera) fmt::print("camera: {}\n", s.camera->to_string());
}

// ---- mesh -------------------------------------------------------------------------------------

struct MapMeshOptions {
  std::string map;
  std::string out;
  std::string device = "cpu";
  MeshParams mesh;
  std::string bounds;
  bool level_colors = false;
  bool no_normals = false;
  bool quiet = false;
};

void run_mesh(const MapMeshOptions& o) {
  const fs::path out(o.out);
  const std::string ext = out.extension().string();
  if (ext != ".ply" && ext != ".obj")
    fail(ErrorCode::InvalidArgument, "--out {}: the mesh file must end in .ply or .obj", o.out);
  MeshParams params = o.mesh;
  params.compute_normals = !o.no_normals;
  if (!o.bounds.empty()) {
    const std::vector<double> v =
        parse_numbers(o.bounds, 6, "--bounds", "xmin,ymin,zmin,xmax,ymax,zmax in metres");
    params.bounds =
        Box3f{{static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2])},
              {static_cast<float>(v[3]), static_cast<float>(v[4]), static_cast<float>(v[5])}};
  }
  params.validate();
  const Device device = Device::parse(o.device);
  check_device(device);  // before the map is read
  LoadedMap loaded = load(o.map, o.quiet);
  const PinholeCamera camera = loaded.info.session.camera.value_or(kDefaultCamera);
  const std::unique_ptr<Reconstruction> rec = on_device(std::move(loaded), device, camera, o.quiet);
  Stopwatch watch;
  RemovedPieces removed;
  TriangleMesh mesh = rec->extract_mesh(params, &removed);
  const std::string pieces =
      params.min_piece_triangles > 0
          ? fmt::format("; removed {} pieces of fewer than {} triangles ({} triangles)",
                        removed.pieces, params.min_piece_triangles, removed.triangles)
          : std::string();
  const double extract_s = watch.lap_ms() / 1e3;
  if (o.level_colors) {
    mesh.colors.resize(mesh.positions_w.size());
    for (std::size_t i = 0; i < mesh.levels.size(); ++i)
      mesh.colors[i] = level_color(mesh.levels[i]);
  }
  if (ext == ".obj")
    write_obj(out, mesh);
  else
    write_ply(out, mesh);
  if (!o.quiet)
    fmt::print("mesh: {} vertices, {} triangles ({}) in {:.2f} s{}, written in {:.2f} s -> {}\n",
               mesh.vertex_count(), mesh.triangle_count(), params.to_string(), extract_s, pieces,
               watch.elapsed_ms() / 1e3, o.out);
  if (mesh.triangle_count() == 0) {
    log::error("{}: the mesh is empty (no surface{} whose voxels were observed {} or more times)",
               o.map, params.bounds ? " inside the bounds" : "", params.min_weight);
    throw ExitStatus{kExitUnusable};
  }
}

// ---- render -----------------------------------------------------------------------------------

struct RenderOptions {
  std::string map;
  std::string pose;
  std::string trajectory;
  std::string camera;
  std::string out;
  float max_depth_m = 0.0f;  ///< 0: the depth range the map was fused with
  int every = 1;
  std::string device = "cpu";
  bool quiet = false;
};

void run_render(const RenderOptions& o) {
  if (o.pose.empty() == o.trajectory.empty())
    fail(ErrorCode::InvalidArgument, "give one of --pose and --trajectory");
  if (!(o.max_depth_m >= 0.0f))
    fail(ErrorCode::InvalidArgument, "--max-depth must be >= 0 m, got {}", o.max_depth_m);
  if (o.every < 1) fail(ErrorCode::InvalidArgument, "--every must be >= 1, got {}", o.every);
  std::vector<StampedPose> poses;
  if (!o.pose.empty()) {
    const std::vector<double> t =
        parse_numbers(o.pose, 7, "--pose", "tx ty tz qx qy qz qw, camera to world");
    poses.push_back({0.0, pose_from_tum(t[0], t[1], t[2], t[3], t[4], t[5], t[6])});
  } else {
    const std::vector<StampedPose> all = read_tum_trajectory(o.trajectory);
    for (std::size_t i = 0; i < all.size(); i += static_cast<std::size_t>(o.every))
      poses.push_back(all[i]);
    if (poses.empty()) fail(ErrorCode::InvalidData, "{}: no poses in the file", o.trajectory);
  }
  const Device device = Device::parse(o.device);
  check_device(device);  // before the map is read
  LoadedMap loaded = load(o.map, o.quiet);
  PinholeCamera camera = kDefaultCamera;
  if (!o.camera.empty()) {
    const std::vector<double> c =
        parse_numbers(o.camera, 6, "--camera", "fx,fy,cx,cy,width,height");
    camera = {static_cast<float>(c[0]), static_cast<float>(c[1]), static_cast<float>(c[2]),
              static_cast<float>(c[3]), static_cast<int>(c[4]),   static_cast<int>(c[5])};
    camera.validate("--camera");
  } else if (loaded.info.session.camera) {
    camera = *loaded.info.session.camera;
  }
  std::error_code ec;
  fs::create_directories(o.out, ec);
  if (ec) fail(ErrorCode::Io, "{}: cannot create the folder ({})", o.out, ec.message());
  // 0: the depth range the map was fused with.
  const float max_depth_m =
      o.max_depth_m > 0.0f ? std::max(o.max_depth_m, loaded.info.fusion.depth_range.min_m) : 0.0f;
  const std::unique_ptr<Reconstruction> rec = on_device(std::move(loaded), device, camera, o.quiet);
  Stopwatch watch;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    write_renders(rec->render(camera, poses[i].T_wc, max_depth_m), rec->params().map, o.out,
                  poses.size() > 1 ? fmt::format("frame{:06d}_", i) : std::string());
    if (!o.quiet && (poses.size() < 20 || (i + 1) % 50 == 0 || i + 1 == poses.size()))
      fmt::print("rendered {}/{}\n", i + 1, poses.size());
  }
  if (!o.quiet)
    fmt::print(
        "{} view(s) of {} ({}) in {:.2f} s -> {}/{}{{depth,normals,shaded,color,levels}}.png\n",
        poses.size(), o.map, camera.to_string(), watch.elapsed_ms() / 1e3, o.out,
        poses.size() > 1 ? "frameNNNNNN_" : "");
}

// ---- export -----------------------------------------------------------------------------------

struct ExportOptions {
  std::string map;
  std::string out;
  bool quiet = false;
};

void run_export(const ExportOptions& o) {
  if (fs::path(o.out).extension() != ".npz")
    fail(ErrorCode::InvalidArgument, "--out {}: the export is numpy's .npz; name it *.npz", o.out);
  const LoadedMap loaded = load(o.map, o.quiet);
  Stopwatch watch;
  write_map_npz(o.out, *loaded.map);
  if (!o.quiet)
    fmt::print(
        "wrote {} in {:.2f} s (numpy.load reads it: level<l>_coords, level<l>_tsdf, "
        "level<l>_weight{}, voxel_size_m, truncation_m)\n",
        o.out, watch.elapsed_ms() / 1e3,
        loaded.map->params().store_color ? ", level<l>_color" : "");
}

void add_threads(CLI::App* cmd, int& threads) {
  cmd->add_option("--threads", threads, "CPU threads (0 = all cores)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
}

}  // namespace

bool print_map_file_info(const std::string& path) {
  if (!is_map_file(path)) return false;
  print_map_info(path);
  return true;
}

void add_map_commands(CLI::App& app) {
  {
    auto o = std::make_shared<MapMeshOptions>();
    auto threads = std::make_shared<int>(0);
    CLI::App* cmd = app.add_subcommand(
        "mesh",
        "Extract a triangle mesh (PLY or OBJ) from a saved map (hivox reconstruct "
        "--save-map). With the run's settings it equals the run's mesh.ply.");
    cmd->add_option("map", o->map, "map file (.hvx)")->required()->type_name("FILE");
    cmd->add_option("--out", o->out, "mesh file: .ply or .obj")->required()->type_name("FILE");
    cmd->add_option("--min-weight", o->mesh.min_weight,
                    "voxels observed fewer times do not make surface")
        ->capture_default_str();
    cmd->add_flag("--level-colors", o->level_colors,
                  "colour vertices by their resolution level (as levels.png) instead of the "
                  "map's colour");
    cmd->add_option("--bounds", o->bounds,
                    "mesh only inside this box: xmin,ymin,zmin,xmax,ymax,zmax (metres, world)");
    cmd->add_option("--min-piece", o->mesh.min_piece_triangles,
                    "remove connected pieces of fewer triangles than this (0 = keep all)")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    cmd->add_flag("--no-normals", o->no_normals, "write no vertex normals");
    cmd->add_option("--device", o->device, kDeviceHelp)->capture_default_str();
    cmd->add_flag("--quiet", o->quiet, "print nothing but warnings and errors");
    add_threads(cmd, *threads);
    cmd->footer(
        "Examples:\n"
        "  hivox mesh rpy.hvx --out rpy.ply\n"
        "  hivox mesh rpy.hvx --out rpy.obj --min-weight 3 --min-piece 200 --bounds "
        "-1,-1,0,1,1,2\n"
        "  hivox mesh rpy.hvx --out levels.ply --level-colors");
    cmd->callback([o, threads] {
      if (*threads > 0) set_thread_count(*threads);
      run_mesh(*o);
    });
  }
  {
    auto o = std::make_shared<RenderOptions>();
    CLI::App* cmd = app.add_subcommand(
        "render",
        "Render a saved map from given camera poses: depth, normals, shaded, colour and "
        "levels PNGs per pose.");
    cmd->add_option("map", o->map, "map file (.hvx)")->required()->type_name("FILE");
    cmd->add_option("--pose", o->pose,
                    "one camera-to-world pose, TUM order: 'tx ty tz qx qy qz qw' (metres)");
    cmd->add_option("--trajectory", o->trajectory,
                    "a TUM trajectory file: one render per pose (frameNNNNNN_*.png)")
        ->type_name("FILE");
    cmd->add_option("--every", o->every, "with --trajectory: every N-th pose")
        ->capture_default_str();
    cmd->add_option("--camera", o->camera,
                    "fx,fy,cx,cy,width,height (default: the camera the map was made with, else "
                    "525,525,319.5,239.5,640,480)");
    cmd->add_option("--max-depth", o->max_depth_m,
                    "render surfaces up to this far, metres (default: the depth range the map was "
                    "fused with, as the run's renders)");
    cmd->add_option("--out", o->out, "output folder")->required()->type_name("DIR");
    cmd->add_option("--device", o->device, kDeviceHelp)->capture_default_str();
    cmd->add_flag("--quiet", o->quiet, "print nothing but warnings and errors");
    cmd->footer(
        "Examples:\n"
        "  hivox render rpy.hvx --pose '1.3 0.6 1.6 0.66 0.62 -0.30 -0.30' --out views\n"
        "  hivox render rpy.hvx --trajectory out/tum_fr1_rpy/trajectory.txt --every 10 --out "
        "views");
    cmd->callback([o] { run_render(*o); });
  }
  {
    auto o = std::make_shared<ExportOptions>();
    CLI::App* cmd = app.add_subcommand(
        "export",
        "Export a saved map's voxels for analysis as numpy's .npz (per level: block "
        "coordinates, TSDF in metres, weights, colour).");
    cmd->add_option("map", o->map, "map file (.hvx)")->required()->type_name("FILE");
    cmd->add_option("--out", o->out, "the .npz file")->required()->type_name("FILE");
    cmd->add_flag("--quiet", o->quiet, "print nothing but warnings and errors");
    cmd->footer(
        "Example:\n"
        "  hivox export rpy.hvx --out rpy.npz\n"
        "  python3 -c \"import numpy as np; m = np.load('rpy.npz'); "
        "print(m['level0_tsdf'].shape)\"");
    cmd->callback([o] { run_export(*o); });
  }
}

}  // namespace hivox::cli

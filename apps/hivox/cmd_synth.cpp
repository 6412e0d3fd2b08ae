// `hivox synth`: render a built-in synthetic scene along its camera path, or a mesh along a
// trajectory (or an orbit), and write a TUM RGB-D sequence (depth + colour PNGs, lists,
// ground-truth poses, intrinsics.json).

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "commands.h"
#include "hivox/core/error.h"
#include "hivox/core/log.h"
#include "hivox/core/timer.h"
#include "hivox/io/intrinsics_io.h"
#include "hivox/io/mesh_file.h"
#include "hivox/io/ply.h"
#include "hivox/io/trajectory_io.h"
#include "hivox/output/tum_export.h"
#include "hivox/synth/synthetic_dataset.h"
#include "hivox/synth_mesh/mesh_dataset.h"

namespace hivox::cli {

namespace {

struct SynthOptions {
  std::string scene = "desk";
  std::size_t frames = 300;
  std::string noise = "kinect";
  std::string out;
  bool overwrite = false;
  int width = 640;
  int height = 480;
  std::uint64_t seed = 1;
  double depth_scale = 5000;
  double max_depth_m = 10.0;
  // Rendering a mesh.
  std::string mesh;
  std::string trajectory;
  std::string intrinsics;
  bool orbit = false;
  std::size_t stride = 1;
  double mesh_scale = 1.0;
  std::string up = "z";
  // Which options the command line set (their defaults differ between scenes and meshes).
  const CLI::Option* frames_option = nullptr;
  const CLI::Option* depth_scale_option = nullptr;
  CLI::Option* size_options[2] = {nullptr, nullptr};
};

// Prints a progress line about ten times over `frames` frames.
ExportProgress progress_printer(std::size_t frames, const Stopwatch& watch) {
  const std::size_t every = std::max<std::size_t>(1, frames / 10);
  return [every, &watch](std::size_t done, std::size_t total) {
    if (done % every == 0 || done == total) {
      const double s = watch.elapsed_ms() / 1000.0;
      fmt::print("  frame {}/{}  {:.1f} fps  {:.1f} s\n", done, total, done / s, s);
      std::fflush(stdout);
    }
  };
}

void run_synth(const SynthOptions& o) {
  SyntheticParams params;
  params.scene = o.scene;
  params.frames = o.frames;
  params.width = o.width;
  params.height = o.height;
  params.noise = noise_preset(o.noise);
  params.noise.seed = o.seed;
  params.max_depth_m = o.max_depth_m;
  SyntheticDataset dataset(params);
  fmt::print("hivox synth: {}\n", params.to_string());
  fmt::print("camera path: {}\n", dataset.scene().camera_path().to_string());
  fmt::print("writing {} frames to {} (depth_scale {})\n", o.frames, o.out, o.depth_scale);

  Stopwatch watch;
  export_tum(dataset, o.out, o.depth_scale, 0, progress_printer(o.frames, watch), o.overwrite);
  fmt::print("done: {} frames in {:.1f} s. Read it back with: hivox info {}\n", o.frames,
             watch.elapsed_ms() / 1000.0, o.out);
}

Eigen::Vector3d up_direction(const std::string& name) {
  const double sign = name[0] == '-' ? -1.0 : 1.0;
  switch (name.back()) {
    case 'x':
      return sign * Eigen::Vector3d::UnitX();
    case 'y':
      return sign * Eigen::Vector3d::UnitY();
    default:
      return sign * Eigen::Vector3d::UnitZ();
  }
}

// The camera-to-world poses of --trajectory, checked: frames are named by their timestamps.
std::vector<StampedPose> read_trajectory(const std::string& path) {
  std::vector<StampedPose> poses = read_tum_trajectory(path);
  if (poses.empty()) fail(ErrorCode::InvalidData, "{}: the trajectory has no poses", path);
  const std::string order = timestamp_order_problems(poses);
  if (!order.empty())
    fail(ErrorCode::InvalidData,
         "{}: {}; frames are named by their timestamps, which must increase", path, order);
  return poses;
}

// The mesh of --mesh in metres (--mesh-scale), with at least one triangle.
TriangleMesh read_scaled_mesh(const std::string& path, double scale) {
  TriangleMesh mesh = read_mesh(path);
  if (mesh.triangles.empty())
    fail(ErrorCode::InvalidArgument,
         "{}: the mesh has no triangles ({} vertices); nothing to render", path,
         mesh.vertex_count());
  if (scale != 1.0)
    for (Vec3f& p : mesh.positions_w) {
      p.x = static_cast<float>(p.x * scale);
      p.y = static_cast<float>(p.y * scale);
      p.z = static_cast<float>(p.z * scale);
    }
  return mesh;
}

// The orbit around the mesh; refuses one whose depths the sequence cannot hold.
std::vector<StampedPose> orbit_poses(const SynthOptions& o, const Aabb& box,
                                     const MeshSequenceParams& params, double depth_scale) {
  const CameraPath path = framing_orbit(box, params.camera);
  const double radius_m = 0.5 * box.size().norm();
  const double far_m = path.distance_m * (1.0 + path.distance_swing) + radius_m;
  const double near_m = path.distance_m * (1.0 - path.distance_swing) - radius_m;
  const std::string size =
      fmt::format("the mesh's bounding box is {:.3g} m across its diagonal at --mesh-scale {}",
                  2 * radius_m, o.mesh_scale);
  if (far_m > params.max_depth_m)
    fail(ErrorCode::InvalidArgument,
         "--orbit: {}, so the orbit sees depths up to {:.3g} m, beyond --max-depth {}; give "
         "--mesh-scale (metres per mesh unit) or raise --max-depth",
         size, far_m, params.max_depth_m);
  if (far_m > 65535.0 / depth_scale)
    fail(ErrorCode::InvalidArgument,
         "--orbit: depths up to {:.3g} m do not fit 16-bit PNGs at --depth-scale {} (at most "
         "{:.3g} m); lower --depth-scale or --mesh-scale",
         far_m, depth_scale, 65535.0 / depth_scale);
  if (params.noise.enabled() && near_m < params.noise.min_depth_m)
    fail(ErrorCode::InvalidArgument,
         "--orbit: {}, so the orbit comes within {:.3g} m, nearer than the {} noise's minimum "
         "depth {} m; give a larger --mesh-scale (metres per mesh unit) or --noise none",
         size, near_m, o.noise, params.noise.min_depth_m);
  fmt::print("orbit: {}, up {}\n", path.to_string(), o.up);
  return make_trajectory_up(path, o.frames, up_direction(o.up));
}

void run_mesh_synth(const SynthOptions& o) {
  namespace fs = std::filesystem;
  if (o.trajectory.empty() && !o.orbit)
    fail(ErrorCode::InvalidArgument,
         "--mesh needs a camera path: --trajectory FILE with --intrinsics FILE, or --orbit");
  if (!o.trajectory.empty() && o.intrinsics.empty())
    fail(ErrorCode::InvalidArgument,
         "--trajectory needs --intrinsics FILE (the camera the trajectory was recorded with)");
  if (!std::isfinite(o.mesh_scale) || o.mesh_scale <= 0.0)
    fail(ErrorCode::InvalidArgument, "--mesh-scale must be > 0 (metres per mesh unit), got {}",
         o.mesh_scale);

  // The small files first: their errors come before the mesh is read.
  MeshSequenceParams params;
  params.noise = noise_preset(o.noise);
  params.noise.seed = o.seed;
  params.max_depth_m = o.max_depth_m;
  params.stride = o.stride;
  double depth_scale = o.depth_scale;
  if (!o.intrinsics.empty()) {
    const IntrinsicsFile file = read_intrinsics_json(o.intrinsics);
    params.camera = file.camera;
    if (!file.distortion.none())
      log::warn(
          "{}: its lens distortion is ignored; frames are rendered through the ideal "
          "pinhole camera (and written without distortion)",
          o.intrinsics);
    if (file.depth_scale > 0.0 && o.depth_scale_option->count() == 0)
      depth_scale = file.depth_scale;
  } else {
    SyntheticParams kinect;  // the built-in scenes' camera: 525 px at 640 wide
    kinect.width = o.width;
    kinect.height = o.height;
    params.camera = kinect.effective_camera();
  }
  std::vector<StampedPose> poses;
  if (!o.trajectory.empty()) {
    poses = read_trajectory(o.trajectory);
    if (o.frames_option->count() > 0) params.max_frames = o.frames;
  }

  const TriangleMesh mesh = read_scaled_mesh(o.mesh, o.mesh_scale);
  std::optional<MeshScene> scene;
  try {
    scene.emplace(mesh);
  } catch (const Error& e) {
    throw Error(e.code(), fmt::format("{}: {}", o.mesh, e.what()));
  }
  const Aabb box = scene->bounds();
  fmt::print("hivox synth: mesh {} ({} vertices, {} triangles, {}), {} m per mesh unit\n", o.mesh,
             mesh.vertex_count(), mesh.triangle_count(),
             scene->has_colors() ? "vertex colours" : "no colours: grey shading", o.mesh_scale);
  fmt::print("  bounds [{:.3f}, {:.3f}, {:.3f}] .. [{:.3f}, {:.3f}, {:.3f}] m\n", box.min_w.x(),
             box.min_w.y(), box.min_w.z(), box.max_w.x(), box.max_w.y(), box.max_w.z());
  fmt::print("camera: {}\n", params.camera.to_string());
  fmt::print("noise: {}, max depth {} m\n", params.noise.enabled() ? o.noise : "none",
             params.max_depth_m);
  std::string source = o.mesh;
  if (o.orbit) {
    poses = orbit_poses(o, box, params, depth_scale);
    source += " (orbit)";
  } else {
    source += " along " + o.trajectory;
  }

  const std::size_t trajectory_size = poses.size();
  MeshDataset dataset(std::move(*scene), poses, params, source);
  if (!o.orbit)
    fmt::print("trajectory: {} ({} poses; stride {}: {} frames)\n", o.trajectory, trajectory_size,
               o.stride, dataset.size());
  // A trajectory in another frame or unit than the mesh sees nothing: say so before writing.
  const RenderedFrame first = dataset.render_clean(0);
  std::size_t seen = 0;
  for (std::size_t k = 0; k < first.depth_m.size(); ++k) seen += first.depth_m.data()[k] > 0.0f;
  if (seen == 0)
    log::warn(
        "frame 0 sees none of the mesh within {} m: are the mesh and the poses in the same "
        "frame and units (--mesh-scale)?",
        params.max_depth_m);
  fmt::print("writing {} frames to {} (depth_scale {})\n", dataset.size(), o.out, depth_scale);

  Stopwatch watch;
  export_tum(dataset, o.out, depth_scale, 0, progress_printer(dataset.size(), watch), o.overwrite);
  const double seconds = watch.elapsed_ms() / 1000.0;
  // The surface in the sequence's world frame (scaled), the reference for `hivox eval mesh`.
  const fs::path mesh_path = fs::path(o.out) / "mesh.ply";
  write_ply(mesh_path, mesh);
  fmt::print(
      "done: {} frames in {:.1f} s ({:.1f} ms per frame), reference mesh {}. Read it back "
      "with: hivox info {}\n",
      dataset.size(), seconds, 1000.0 * seconds / dataset.size(), mesh_path.string(), o.out);
}

}  // namespace

void add_synth_command(CLI::App& app) {
  auto o = std::make_shared<SynthOptions>();
  CLI::App* cmd = app.add_subcommand(
      "synth",
      "Render a built-in synthetic scene, or a mesh along a trajectory or an orbit (exact "
      "geometry, known poses, optional Kinect-like noise), and write it as a TUM RGB-D sequence: "
      "rgb/, depth/ (16-bit PNG), rgb.txt, depth.txt, associations.txt, groundtruth.txt, "
      "intrinsics.json (and mesh.ply, the mesh rendered, for a mesh).");
  cmd->footer(
      "Scenes (metres, z up):\n"
      "  room      4.0 x 3.2 x 2.5 m room with a table (top at 0.75 m): large flat areas\n"
      "  desk      the room + keyboard, bumpy blob, box, monitor, mug, spheres (demo scene)\n"
      "  box       a 30 x 20 x 16 cm box with rounded edges, seen from all sides\n"
      "  spheres   five spheres of radius 3-12 cm, seen from all sides\n"
      "  keyboard  a 45 x 15 cm keyboard (15 mm keys, 4 mm gaps), seen from all sides\n"
      "  blob      a ~22 cm bumpy organic blob (bumps of 1-4 cm), seen from all sides\n"
      "Indoor scenes use an arc in front of the table, single objects a full orbit; the path\n"
      "is closed and spread over --frames frames (30 Hz timestamps).\n"
      "The same scenes are readable directly as datasets: synthetic:desk?frames=100&noise=none\n"
      "\n"
      "Meshes (--mesh, PLY/OBJ/OFF; vertex colours are interpolated, else grey shading):\n"
      "  --trajectory FILE --intrinsics FILE  the camera of intrinsics.json at the poses of a TUM\n"
      "      trajectory (camera-to-world, OpenCV axes), each --stride-th pose, at most --frames;\n"
      "      depth PNGs use the file's depth_scale unless --depth-scale is given\n"
      "  --orbit  a closed orbit around the mesh's bounding box at the distance that fits it in\n"
      "      view (--frames frames); without --intrinsics the 640x480 Kinect-like camera. Models\n"
      "      in other units need --mesh-scale (metres per unit), other up axes --up\n"
      "\n"
      "Examples:\n"
      "  hivox synth --scene desk --frames 300 --noise kinect --out out/desk\n"
      "  hivox synth --mesh office0.ply --trajectory groundtruth.txt --intrinsics "
      "intrinsics.json --stride 2 --frames 300 --noise none --out out/office0\n"
      "  hivox synth --mesh armadillo.off --orbit --mesh-scale 0.004 --up y --out out/armadillo");
  CLI::Option* scene = cmd->add_option("--scene", o->scene, "Scene to render")
                           ->check(CLI::IsMember(scene_names()))
                           ->capture_default_str();
  o->frames_option =
      cmd->add_option("--frames", o->frames,
                      "Number of frames along the camera path (scenes, --orbit); with "
                      "--trajectory at most this many (default: all)")
          ->check(CLI::PositiveNumber)
          ->capture_default_str();
  cmd->add_option("--noise", o->noise,
                  "Depth noise: 'kinect' (Nguyen et al. 2012 axial noise, lateral jitter, "
                  "1/8-pixel disparity quantisation, grazing-angle and edge dropouts) or 'none'")
      ->check(CLI::IsMember(noise_preset_names()))
      ->capture_default_str();
  cmd->add_option("--out", o->out,
                  "Output directory (created if missing; written whole when the export ends)")
      ->required();
  cmd->add_flag("--overwrite", o->overwrite,
                "replace an output directory that holds files already (without it such a "
                "directory is refused, so that two sequences' frames never mix)");
  o->size_options[0] =
      cmd->add_option("--width", o->width, "Image width, pixels (focal length scales with it)")
          ->check(CLI::PositiveNumber)
          ->capture_default_str();
  o->size_options[1] = cmd->add_option("--height", o->height, "Image height, pixels")
                           ->check(CLI::PositiveNumber)
                           ->capture_default_str();
  cmd->add_option("--seed", o->seed, "Seed of the depth noise")->capture_default_str();
  o->depth_scale_option =
      cmd->add_option("--depth-scale", o->depth_scale,
                      "Depth PNG units per metre (TUM: 5000, i.e. 0.2 mm steps; with "
                      "--intrinsics the file's depth_scale when it has one)")
          ->check(CLI::PositiveNumber)
          ->capture_default_str();
  cmd->add_option("--max-depth", o->max_depth_m, "Rendered depth beyond this is invalid, metres")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();

  CLI::Option* mesh =
      cmd->add_option("--mesh", o->mesh, "Render this mesh (.ply, .obj, .off) instead of a scene")
          ->excludes(scene);
  CLI::Option* trajectory =
      cmd->add_option("--trajectory", o->trajectory,
                      "With --mesh: TUM trajectory (t tx ty tz qx qy qz qw, camera-to-world) to "
                      "render along")
          ->needs(mesh);
  CLI::Option* intrinsics =
      cmd->add_option("--intrinsics", o->intrinsics,
                      "With --mesh: intrinsics.json of the camera (fx fy cx cy width height "
                      "[depth_scale])")
          ->needs(mesh);
  for (CLI::Option* size : {o->size_options[0], o->size_options[1]}) size->excludes(intrinsics);
  cmd->add_flag("--orbit", o->orbit,
                "With --mesh: render along a closed orbit around the mesh instead of a trajectory")
      ->needs(mesh)
      ->excludes(trajectory);
  cmd->add_option("--stride", o->stride, "With --trajectory: render every K-th pose")
      ->needs(trajectory)
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--mesh-scale", o->mesh_scale,
                  "With --mesh: metres per mesh unit (the sequence and mesh.ply are in metres)")
      ->needs(mesh)
      ->capture_default_str();
  cmd->add_option("--up", o->up, "With --orbit: the mesh's up axis")
      ->needs("--orbit")
      ->check(CLI::IsMember({"x", "y", "z", "-x", "-y", "-z"}))
      ->capture_default_str();
  cmd->callback([o] {
    if (o->mesh.empty())
      run_synth(*o);
    else
      run_mesh_synth(*o);
  });
}

}  // namespace hivox::cli

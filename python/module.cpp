// The `hivox` Python module (pybind11): parameter structs, datasets, the library-level run, the
// per-frame Reconstruction with numpy images in and numpy renders and meshes out, map files.
// Heavy calls release the GIL. Errors are `hivox.Error` (a RuntimeError) with the library's
// one-line message.

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <array>
#include <cstring>
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "hivox/core/error.h"
#include "hivox/core/version.h"
#include "hivox/io/dataset.h"
#include "hivox/io/map_file.h"
#include "hivox/io/obj.h"
#include "hivox/io/ply.h"
#include "hivox/io/read_ahead.h"
#include "hivox/mesh/extract_mesh.h"
#include "hivox/pipeline/reconstruction.h"
#include "hivox/run/devices.h"
#include "hivox/run/runner.h"

namespace py = pybind11;
using namespace hivox;

namespace {

/// `T(**kwargs)`: a default T with each keyword set as an attribute; an unknown keyword is a
/// TypeError naming it.
template <typename T>
void keyword_init(py::class_<T>& cls) {
  cls.def(py::init([cls](const py::kwargs& kwargs) {
    py::object obj = py::cast(T{});
    for (const auto& [key, value] : kwargs) {
      const std::string name = py::cast<std::string>(key);
      if (!py::hasattr(cls, name.c_str()))
        throw py::type_error(
            fmt::format("{}: no field '{}'", py::cast<std::string>(cls.attr("__name__")), name));
      obj.attr(name.c_str()) = value;
    }
    return obj.cast<T>();
  }));
}

/// A field of `T` that holds a choice, read and set by its name as the CLI spells it
/// (`hivox::to_string` and `parse`; a bad name raises the library's error).
template <typename T, typename E, typename Parse>
void name_property(py::class_<T>& cls, const char* name, E T::*field, Parse parse,
                   const char* doc) {
  cls.def_property(
      name, [field](const T& p) { return std::string(to_string(p.*field)); },
      [field, parse](T& p, const std::string& v) { p.*field = parse(v); }, doc);
}

template <typename T>
std::string repr_of(const char* name, const T& v) {
  return fmt::format("hivox.{}({})", name, v.to_string());
}

/// A numpy array of `rows` x `cols` elements of type T copied from `data`.
template <typename T>
py::array_t<T> array_2d(const T* data, py::ssize_t rows, py::ssize_t cols) {
  py::array_t<T> a({rows, cols});
  if (rows * cols > 0) std::memcpy(a.mutable_data(), data, sizeof(T) * rows * cols);
  return a;
}

/// Depth in metres from a numpy image: float32/float64 metres, or uint16 raw units divided by
/// `depth_scale`.
DepthImage depth_from_array(const py::array& depth, double depth_scale) {
  if (depth.ndim() != 2) throw py::value_error("depth must be a 2-D array (height, width)");
  const int h = static_cast<int>(depth.shape(0)), w = static_cast<int>(depth.shape(1));
  DepthImage out(w, h);
  if (py::isinstance<py::array_t<uint16_t>>(depth)) {
    if (!(depth_scale > 0))
      throw py::value_error("uint16 depth needs depth_scale > 0 (raw units per metre)");
    const auto d = py::array_t<uint16_t, py::array::c_style | py::array::forcecast>(depth);
    const uint16_t* p = d.data();
    for (std::size_t i = 0; i < out.size(); ++i)
      out.data()[i] = static_cast<float>(p[i] / depth_scale);
    return out;
  }
  if (depth.dtype().kind() != 'f')
    throw py::value_error("depth must be uint16 (raw units) or float (metres)");
  const auto d = py::array_t<float, py::array::c_style | py::array::forcecast>(depth);
  std::memcpy(out.data(), d.data(), sizeof(float) * out.size());
  return out;
}

ColorImage color_from_array(const py::object& color, int width, int height) {
  if (color.is_none()) return {};
  const auto c = py::array_t<uint8_t, py::array::c_style | py::array::forcecast>(color);
  if (c.ndim() != 3 || c.shape(2) != 3 || c.shape(0) != height || c.shape(1) != width)
    throw py::value_error(
        fmt::format("color must be a uint8 array of shape ({}, {}, 3)", height, width));
  ColorImage out(width, height);
  std::memcpy(out.data(), c.data(), 3 * out.size());
  return out;
}

Pose pose_from(const Eigen::Matrix4d& m) {
  Pose T = Pose::Identity();
  T.matrix() = m;
  return T;
}

/// A frame as Python sees it (Dataset.read).
py::dict frame_dict(const RgbdFrame& f) {
  py::dict d;
  d["index"] = f.index;
  d["timestamp_s"] = f.timestamp_s;
  d["depth"] = array_2d(f.depth_m.data(), f.depth_m.height(), f.depth_m.width());
  if (!f.color.empty()) {
    py::array_t<uint8_t> c(
        {py::ssize_t{f.color.height()}, py::ssize_t{f.color.width()}, py::ssize_t{3}});
    std::memcpy(c.mutable_data(), f.color.data(), 3 * f.color.size());
    d["color"] = c;
  } else {
    d["color"] = py::none();
  }
  d["T_wc_gt"] = f.T_wc_gt ? py::cast(Eigen::Matrix4d(f.T_wc_gt->matrix())) : py::none();
  return d;
}

/// Dataset.frames: the frames read ahead, the dataset kept alive while they are.
struct FrameIterator {
  FrameIterator(std::shared_ptr<DatasetReader> r, std::size_t first, std::size_t end, int threads)
      : reader(std::move(r)),
        frames(*reader, first, end, ReadAhead::frames_for(threads), threads) {}
  std::shared_ptr<DatasetReader> reader;
  ReadAhead frames;
};

py::dict frame_stats_dict(const FrameStats& s) {
  py::dict d;
  d["index"] = s.index;
  d["timestamp_s"] = s.timestamp_s;
  d["fused"] = s.fused;
  d["tracking"] = s.tracking == TrackingQuality::Good   ? "good"
                  : s.tracking == TrackingQuality::Poor ? "poor"
                                                        : "lost";
  d["total_ms"] = s.total_ms;
  d["track_ms"] = s.track_ms;
  d["integrate_ms"] = s.integrate_ms;
  d["raycast_ms"] = s.raycast_ms;
  d["valid_pixels"] = s.valid_pixels;
  d["blocks_total"] = s.blocks_total;
  d["blocks_per_level"] = s.blocks_per_level;
  d["dropped_blocks"] = s.dropped_blocks;
  d["splits"] = s.splits;
  d["merges"] = s.merges;
  d["track_iterations"] = s.track_iterations;
  d["track_inlier_ratio"] = s.track_inlier_ratio;
  return d;
}

py::dict raycast_dict(const RaycastResult& r) {
  const py::ssize_t h = r.depth_m.height(), w = r.depth_m.width();
  py::dict d;
  d["depth"] = array_2d(r.depth_m.data(), h, w);
  py::array_t<float> normals({h, w, py::ssize_t{3}});
  std::memcpy(normals.mutable_data(), r.normals_w.data(), sizeof(float) * 3 * h * w);
  d["normals"] = normals;
  py::array_t<uint8_t> color({h, w, py::ssize_t{3}});
  std::memcpy(color.mutable_data(), r.colors.data(), 3 * h * w);
  d["color"] = color;
  d["levels"] = array_2d(r.levels.data(), h, w);
  return d;
}

py::dict mesh_dict(const TriangleMesh& m) {
  py::dict d;
  const auto n = static_cast<py::ssize_t>(m.positions_w.size());
  d["vertices"] = array_2d(reinterpret_cast<const float*>(m.positions_w.data()), n, 3);
  d["triangles"] = array_2d(reinterpret_cast<const int32_t*>(m.triangles.data()),
                            static_cast<py::ssize_t>(m.triangles.size()), 3);
  if (!m.normals_w.empty())
    d["normals"] = array_2d(reinterpret_cast<const float*>(m.normals_w.data()), n, 3);
  if (!m.colors.empty())
    d["colors"] = array_2d(reinterpret_cast<const uint8_t*>(m.colors.data()), n, 3);
  if (!m.levels.empty()) d["levels"] = array_2d(m.levels.data(), n, 1).reshape({n});
  return d;
}

py::dict summary_dict(const RunSummary& s) {
  py::dict d;
  d["frames_total"] = s.frames_total;
  d["frames_fused"] = s.frames_fused;
  d["frames_lost"] = s.frames_lost;
  d["frames_skipped"] = s.frames_skipped;
  d["frames_bad"] = s.frames_bad;
  d["end"] = s.end == RunEnd::Completed       ? "completed"
             : s.end == RunEnd::StopRequested ? "stopped"
                                              : "bad frame";
  d["warnings"] = s.warnings;
  d["unusable"] = s.unusable;
  d["wall_s"] = s.wall_s;
  d["processing_s"] = s.processing_s;
  if (s.ate) d["ate_rmse_m"] = s.ate->rmse_m;
  d["mesh_vertices"] = s.mesh_vertices;
  d["mesh_triangles"] = s.mesh_triangles;
  std::vector<std::string> files;
  for (const auto& f : s.files) files.push_back(f.string());
  d["files"] = files;
  return d;
}

}  // namespace

PYBIND11_MODULE(hivox, m) {
  m.doc() =
      "hivox: dense 3D reconstruction from RGB-D images with hierarchical voxel block hashing";
  m.attr("__version__") = std::string(library_version());
  static py::exception<Error> error(m, "Error", PyExc_RuntimeError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const Error& e) {
      error(e.what());
    }
  });

  py::class_<PinholeCamera> camera(m, "PinholeCamera");
  keyword_init(camera);
  camera.def_readwrite("fx", &PinholeCamera::fx)
      .def_readwrite("fy", &PinholeCamera::fy)
      .def_readwrite("cx", &PinholeCamera::cx)
      .def_readwrite("cy", &PinholeCamera::cy)
      .def_readwrite("width", &PinholeCamera::width)
      .def_readwrite("height", &PinholeCamera::height)
      .def("validate", [](const PinholeCamera& c) { c.validate(); })
      .def("__repr__", [](const PinholeCamera& c) { return repr_of("PinholeCamera", c); });

  py::class_<MapParams> map(m, "MapParams");
  keyword_init(map);
  map.def_readwrite("voxel_size_m", &MapParams::voxel_size_m)
      .def_readwrite("levels", &MapParams::levels)
      .def_readwrite("truncation_m", &MapParams::truncation_m)
      .def_readwrite("max_blocks", &MapParams::max_blocks)
      .def_readwrite("buckets_per_level", &MapParams::buckets_per_level)
      .def_readwrite("excess_per_level", &MapParams::excess_per_level)
      .def_readwrite("store_color", &MapParams::store_color)
      .def("validate", &MapParams::validate)
      .def("__repr__", [](const MapParams& p) { return repr_of("MapParams", p); });

  py::class_<FusionParams> fusion(m, "FusionParams");
  keyword_init(fusion);
  fusion.def_readwrite("max_weight", &FusionParams::max_weight)
      .def_property(
          "min_depth_m", [](const FusionParams& p) { return p.depth_range.min_m; },
          [](FusionParams& p, float v) { p.depth_range.min_m = v; })
      .def_property(
          "max_depth_m", [](const FusionParams& p) { return p.depth_range.max_m; },
          [](FusionParams& p, float v) { p.depth_range.max_m = v; })
      .def_readwrite("integrate_color", &FusionParams::integrate_color)
      .def("validate", &FusionParams::validate)
      .def("__repr__", [](const FusionParams& p) { return repr_of("FusionParams", p); });
  name_property(fusion, "depth_sampling", &FusionParams::depth_sampling, parse_depth_sampling,
                "how a voxel reads the depth image: 'bilinear' or 'nearest'");

  py::class_<SensorNoise> noise(m, "SensorNoise");
  keyword_init(noise);
  noise.def_readwrite("sigma_min_m", &SensorNoise::sigma_min_m)
      .def_readwrite("quadratic_per_m", &SensorNoise::quadratic_per_m)
      .def_readwrite("z0_m", &SensorNoise::z0_m)
      .def("sigma_m", &SensorNoise::sigma_m, py::arg("z_m"),
           "the axial noise sigma at depth z_m: sigma_min_m + quadratic_per_m * max(0, z_m - "
           "z0_m)^2, metres")
      .def_static("kinect", &SensorNoise::kinect, "a structured-light Kinect's (the default)")
      .def_static("none", &SensorNoise::none, "a perfect sensor's (noise-free synthetic depth)")
      .def("__repr__", [](const SensorNoise& n) {
        return fmt::format("hivox.SensorNoise(sigma_min_m={:g}, quadratic_per_m={:g}, z0_m={:g})",
                           n.sigma_min_m, n.quadratic_per_m, n.z0_m);
      });

  py::class_<RefineParams> refine(m, "RefineParams");
  keyword_init(refine);
  name_property(refine, "criterion", &RefineParams::criterion, parse_refine_criterion,
                "complexity criterion: 'detail' or 'det-cov' (the paper's)");
  refine.def_readwrite("split_threshold", &RefineParams::split_threshold)
      .def_readwrite("merge_threshold", &RefineParams::merge_threshold)
      .def_readwrite("split_noise_factor", &RefineParams::split_noise_factor)
      .def_readwrite("every_n_frames", &RefineParams::every_n_frames)
      .def_readwrite("min_weight", &RefineParams::min_weight)
      .def_readwrite("min_updates", &RefineParams::min_updates)
      .def_readwrite("split_unmeshable_cells", &RefineParams::split_unmeshable_cells)
      .def_readwrite("unmeshable_min_weight", &RefineParams::unmeshable_min_weight)
      .def_readwrite("merge_noise_ratio", &RefineParams::merge_noise_ratio)
      .def_readwrite("settled_weight", &RefineParams::settled_weight)
      .def_readwrite("min_samples", &RefineParams::min_samples)
      .def_readwrite("split_weight_scale", &RefineParams::split_weight_scale)
      .def_readwrite("noise", &RefineParams::noise,
                     "the sensor noise the thresholds compare detail with (a SensorNoise; None: "
                     "the camera's own)")
      .def("validate", &RefineParams::validate)
      .def("__repr__", [](const RefineParams& p) {
        return fmt::format("hivox.RefineParams({})", p.to_string(std::nullopt));
      });

  py::class_<TrackParams> track(m, "TrackParams");
  keyword_init(track);
  track.def_readwrite("bilateral_radius_px", &TrackParams::bilateral_radius_px)
      .def_readwrite("bilateral_sigma_px", &TrackParams::bilateral_sigma_px)
      .def_readwrite("bilateral_sigma_depth_m", &TrackParams::bilateral_sigma_depth_m)
      .def_readwrite("max_depth_jump_ratio", &TrackParams::max_depth_jump_ratio)
      .def_readwrite("iterations", &TrackParams::iterations,
                     "Gauss-Newton iterations per pyramid level, finest first (a list: assign a "
                     "new one; its length is the number of levels)")
      .def_readwrite("max_distance_m", &TrackParams::max_distance_m)
      .def_readwrite("max_normal_angle_deg", &TrackParams::max_normal_angle_deg)
      .def_readwrite("noise", &TrackParams::noise,
                     "the depth noise residuals are weighted by (a SensorNoise)")
      .def_readwrite("robust_scale", &TrackParams::robust_scale)
      .def_readwrite("residual_floor_m", &TrackParams::residual_floor_m)
      .def_readwrite("constant_velocity", &TrackParams::constant_velocity)
      .def_readwrite("model_subsample", &TrackParams::model_subsample,
                     "the model is raycast at 1/N of the frame's resolution (1, 2 or 4)")
      .def_readwrite("convergence_step", &TrackParams::convergence_step)
      .def_readwrite("lost_inlier_ratio", &TrackParams::lost_inlier_ratio)
      .def_readwrite("poor_inlier_ratio", &TrackParams::poor_inlier_ratio)
      .def_readwrite("lost_rms_m", &TrackParams::lost_rms_m)
      .def_readwrite("poor_condition", &TrackParams::poor_condition)
      .def_readwrite("lost_jump_m", &TrackParams::lost_jump_m)
      .def_readwrite("lost_jump_deg", &TrackParams::lost_jump_deg)
      .def("validate", &TrackParams::validate)
      .def("__repr__", [](const TrackParams& p) { return repr_of("TrackParams", p); });
  name_property(track, "loss", &TrackParams::loss, parse_robust_loss,
                "robust loss of the residuals: 'none', 'huber' or 'tukey'");

  py::class_<RaycastParams> raycast(m, "RaycastParams");
  keyword_init(raycast);
  raycast.def_readwrite("step_fraction", &RaycastParams::step_fraction)
      .def_readwrite("min_weight", &RaycastParams::min_weight)
      .def_readwrite("hint_margin_mu", &RaycastParams::hint_margin_mu)
      .def_readwrite("hint_agreement_mu", &RaycastParams::hint_agreement_mu)
      .def("validate", &RaycastParams::validate)
      .def("__repr__", [](const RaycastParams& p) { return repr_of("RaycastParams", p); });

  py::class_<MeshParams> mesh(m, "MeshParams");
  keyword_init(mesh);
  mesh.def_readwrite("min_weight", &MeshParams::min_weight)
      .def_readwrite("compute_normals", &MeshParams::compute_normals)
      .def_readwrite("with_color", &MeshParams::with_color)
      .def_readwrite("min_piece_triangles", &MeshParams::min_piece_triangles)
      .def_property(
          "bounds",
          [](const MeshParams& p) -> py::object {
            if (!p.bounds) return py::none();
            const Box3f& b = *p.bounds;
            return py::make_tuple(py::make_tuple(b.min_m.x, b.min_m.y, b.min_m.z),
                                  py::make_tuple(b.max_m.x, b.max_m.y, b.max_m.z));
          },
          [](MeshParams& p,
             const std::optional<std::pair<std::array<float, 3>, std::array<float, 3>>>& v) {
            if (!v) {
              p.bounds.reset();
              return;
            }
            const auto& [lo, hi] = *v;
            const Box3f box{{lo[0], lo[1], lo[2]}, {hi[0], hi[1], hi[2]}};
            box.validate("mesh bounds");
            p.bounds = box;
          },
          "mesh only this box, ((xmin, ymin, zmin), (xmax, ymax, zmax)) in metres, world frame "
          "(None: everything); triangles with a corner outside are left out")
      .def("validate", &MeshParams::validate)
      .def("__repr__", [](const MeshParams& p) { return repr_of("MeshParams", p); });

  py::class_<ReconstructionParams> rec_params(m, "ReconstructionParams");
  keyword_init(rec_params);
  rec_params.def_readwrite("map", &ReconstructionParams::map)
      .def_readwrite("fusion", &ReconstructionParams::fusion)
      .def_readwrite("refine", &ReconstructionParams::refine)
      .def_readwrite("track", &ReconstructionParams::track)
      .def_readwrite("raycast", &ReconstructionParams::raycast)
      .def_readwrite("raycast_every_frame", &ReconstructionParams::raycast_every_frame)
      .def_readwrite("previous_raycast_hints", &ReconstructionParams::previous_raycast_hints)
      .def_readwrite("refine_after_raycast", &ReconstructionParams::refine_after_raycast)
      .def_property(
          "device", [](const ReconstructionParams& p) { return p.device.to_string(); },
          [](ReconstructionParams& p, const std::string& name) { p.device = Device::parse(name); },
          "where the frames run: 'cpu', or 'cuda' / 'cuda:N' (builds with the CUDA loop)")
      .def("validate", &ReconstructionParams::validate)
      .def("__repr__", [](const ReconstructionParams& p) {
        return "hivox.ReconstructionParams(\n" + p.to_string() + ")";
      });

  py::class_<RunParams> run(m, "RunParams");
  keyword_init(run);
  run.def_readwrite("reconstruction", &RunParams::reconstruction)
      .def_property(
          "poses", [](const RunParams& p) { return p.poses.to_string(); },
          [](RunParams& p, const std::string& s) { p.poses = PoseSpec::parse(s); })
      .def_readwrite("first_frame", &RunParams::first_frame)
      .def_readwrite("max_frames", &RunParams::max_frames)
      .def_readwrite("mesh", &RunParams::mesh)
      .def_readwrite("out_dir", &RunParams::out_dir)
      .def_readwrite("overwrite", &RunParams::overwrite)
      .def_readwrite("read_ahead_frames", &RunParams::read_ahead_frames)
      .def_readwrite("read_threads", &RunParams::read_threads)
      .def_readwrite("map_in", &RunParams::map_in)
      .def_readwrite("map_out", &RunParams::map_out)
      .def("validate", &RunParams::validate)
      .def("__repr__", [](const RunParams& p) {
        return fmt::format("hivox.RunParams(poses={}, first_frame={}, max_frames={}, out_dir='{}')",
                           p.poses.to_string(), p.first_frame, p.max_frames, p.out_dir.string());
      });

  py::class_<DatasetReader, std::shared_ptr<DatasetReader>>(m, "Dataset")
      .def("__len__", &DatasetReader::size)
      .def_property_readonly("camera",
                             [](const DatasetReader& r) { return r.info().rig.depth_camera; })
      .def_property_readonly("depth_scale",
                             [](const DatasetReader& r) { return r.info().rig.depth_scale; })
      .def_property_readonly(
          "layout", [](const DatasetReader& r) { return std::string(to_string(r.info().layout)); })
      .def_property_readonly("has_ground_truth",
                             [](const DatasetReader& r) { return r.info().has_ground_truth; })
      .def("describe", [](DatasetReader& r) { return describe_dataset(r); })
      .def(
          "read",
          [](DatasetReader& r, std::size_t i) {
            if (i >= r.size()) throw py::index_error(fmt::format("frame {} of {}", i, r.size()));
            RgbdFrame f;
            {
              py::gil_scoped_release release;
              f = r.read(i);
            }
            return frame_dict(f);
          },
          py::arg("index"),
          "Frame `index`: depth (float32 metres), color (uint8 or None), "
          "timestamp_s, T_wc_gt (4x4 or None).")
      .def(
          "frames",
          [](const std::shared_ptr<DatasetReader>& r, std::size_t first, std::size_t count,
             int threads) {
            if (first > r->size())
              throw py::index_error(fmt::format("first frame {} of {}", first, r->size()));
            const std::size_t end = count == 0 ? r->size() : std::min(r->size(), first + count);
            return std::make_unique<FrameIterator>(r, first, end, threads);
          },
          py::arg("first") = 0, py::arg("count") = 0, py::arg("threads") = 2,
          "Iterates over frames [first, first + count) (count 0: to the end) as `read` gives "
          "them, decoded ahead on `threads` threads (0: each when asked for). While it lives, "
          "the dataset is read by it.");

  py::class_<FrameIterator>(m, "FrameIterator")
      .def("__iter__", [](FrameIterator& it) -> FrameIterator& { return it; })
      .def("__next__", [](FrameIterator& it) {
        if (it.frames.left() == 0) throw py::stop_iteration();
        RgbdFrame f;
        {
          py::gil_scoped_release release;
          f = it.frames.next();
        }
        return frame_dict(f);
      });

  m.def(
      "devices",
      [] {
        py::list out;
        for (const DeviceInfo& d : list_devices().devices) {
          py::dict e;
          e["device"] = d.device.to_string();
          e["name"] = d.name;
          if (!d.device.is_cpu()) {
            e["memory_bytes"] = d.memory_bytes;
            e["free_bytes"] = d.free_bytes;
            e["compute_capability"] = py::make_tuple(d.compute_major, d.compute_minor);
            e["multiprocessors"] = d.multiprocessors;
          }
          out.append(e);
        }
        return out;
      },
      "The devices ReconstructionParams.device can name: a dict each ('device', 'name'; for a "
      "GPU also 'memory_bytes', 'free_bytes', 'compute_capability', 'multiprocessors'), the CPU "
      "first. CUDA devices are listed in builds with the CUDA loop only.");

  m.def(
      "open_dataset",
      [](const std::string& path, const std::string& preset, double depth_scale,
         const std::string& intrinsics, std::size_t max_frames) {
        DatasetParams p;
        p.preset = preset;
        p.depth_scale = depth_scale;
        p.intrinsics_path = intrinsics;
        p.max_frames = max_frames;
        return std::shared_ptr<DatasetReader>(open_dataset(path, p));
      },
      py::arg("path"), py::arg("preset") = "", py::arg("depth_scale") = 0.0,
      py::arg("intrinsics") = "", py::arg("max_frames") = 0,
      "Opens a dataset folder (TUM, 7-Scenes, InfiniTAM, Open3D, image folder) or a built-in "
      "scene ('synthetic:desk?frames=100').");

  py::class_<Reconstruction>(m, "Reconstruction")
      .def(py::init([](const ReconstructionParams& params, const PinholeCamera& camera,
                       double depth_scale, bool noise_free,
                       const std::optional<SensorNoise>& depth_noise) {
             CameraRig rig = CameraRig::registered(camera);
             rig.depth_scale = depth_scale;
             if (noise_free && depth_noise)
               throw Error(ErrorCode::InvalidArgument,
                           "Reconstruction: noise_free and depth_noise both given; pass one");
             if (noise_free) rig.depth_noise = SensorNoise::none();
             if (depth_noise) rig.depth_noise = *depth_noise;
             return make_reconstruction(params, rig);
           }),
           py::arg("params"), py::arg("camera"), py::arg("depth_scale") = 0.0,
           py::arg("noise_free") = false, py::arg("depth_noise") = py::none(),
           "A reconstruction of frames from one registered RGB-D camera. depth_scale: raw units "
           "per metre of uint16 depth images (float depth is metres). depth_noise: the camera's "
           "axial noise (a SensorNoise; default a Kinect's), which refinement's thresholds compare "
           "detail with unless RefineParams.noise says otherwise; noise_free=True is "
           "SensorNoise.none().")
      .def(
          "integrate",
          [](Reconstruction& r, const py::array& depth, const py::object& color,
             const Eigen::Matrix4d& T_wc) {
            RgbdFrame f;
            f.index = r.frame_stats().size();
            f.depth_m = depth_from_array(depth, r.rig().depth_scale);
            f.color = color_from_array(color, f.depth_m.width(), f.depth_m.height());
            const Pose pose = pose_from(T_wc);
            FrameStats s;
            {
              py::gil_scoped_release release;
              s = r.integrate(f, pose);
            }
            return frame_stats_dict(s);
          },
          py::arg("depth"), py::arg("color") = py::none(), py::arg("T_wc"),
          "Fuses a frame at camera-to-world pose T_wc (4x4); returns its statistics.")
      .def(
          "track_and_integrate",
          [](Reconstruction& r, const py::array& depth, const py::object& color,
             const std::optional<Eigen::Matrix4d>& T_wc_first) {
            RgbdFrame f;
            f.index = r.frame_stats().size();
            f.depth_m = depth_from_array(depth, r.rig().depth_scale);
            f.color = color_from_array(color, f.depth_m.width(), f.depth_m.height());
            const Pose first = T_wc_first ? pose_from(*T_wc_first) : Pose::Identity();
            FrameStats s;
            {
              py::gil_scoped_release release;
              s = r.track_and_integrate(f, 0.0, first);
            }
            py::dict d = frame_stats_dict(s);
            d["T_wc"] = Eigen::Matrix4d(r.trajectory().back().T_wc.matrix());
            return d;
          },
          py::arg("depth"), py::arg("color") = py::none(), py::arg("T_wc_first") = py::none(),
          "Tracks the frame against the model (ICP), fuses it there; returns its statistics "
          "and pose T_wc.")
      .def(
          "render",
          [](Reconstruction& r, const PinholeCamera& camera, const Eigen::Matrix4d& T_wc,
             float max_depth_m) {
            const Pose pose = pose_from(T_wc);
            RaycastResult result;
            {
              py::gil_scoped_release release;
              result = r.render(camera, pose, max_depth_m);
            }
            return raycast_dict(result);
          },
          py::arg("camera"), py::arg("T_wc"), py::arg("max_depth_m") = 0.0f,
          "Raycasts the model: depth (float32 m, 0 = no hit), normals (world), color (uint8), "
          "levels (int8, -1 = no hit).")
      .def(
          "last_raycast",
          [](const Reconstruction& r) {
            RaycastResult result;
            {
              py::gil_scoped_release release;
              result = r.last_raycast();
            }
            return raycast_dict(result);
          },
          "The model raycast the last frame was fused with, which the next one tracks against, "
          "at the tracking model's resolution (track.model_subsample; empty before the first "
          "frame): the arrays of render().")
      .def(
          "extract_mesh",
          [](const Reconstruction& r, const MeshParams& params) {
            TriangleMesh mesh;
            {
              py::gil_scoped_release release;
              mesh = r.extract_mesh(params);
            }
            return mesh_dict(mesh);
          },
          py::arg("params") = MeshParams{},
          "The mesh: vertices (N, 3) float32, triangles (M, 3) int32, normals, colors, levels.")
      .def(
          "write_mesh",
          [](const Reconstruction& r, const std::filesystem::path& path, const MeshParams& params) {
            py::gil_scoped_release release;
            const TriangleMesh mesh = r.extract_mesh(params);
            if (path.extension() == ".obj")
              write_obj(path, mesh);
            else
              write_ply(path, mesh);
          },
          py::arg("path"), py::arg("params") = MeshParams{}, "Writes the mesh as .ply or .obj.")
      .def(
          "save_map",
          [](const Reconstruction& r, const std::filesystem::path& path) {
            py::gil_scoped_release release;
            write_map_file(path, r.map(), r.params().fusion, r.session());
          },
          py::arg("path"), "Saves the map (.hvx), to be continued or meshed later.")
      .def_property_readonly(
          "trajectory",
          [](const Reconstruction& r) {
            py::list out;
            for (const StampedPose& p : r.trajectory())
              out.append(py::make_tuple(p.timestamp_s, Eigen::Matrix4d(p.T_wc.matrix())));
            return out;
          })
      .def_property_readonly("frame_stats",
                             [](const Reconstruction& r) {
                               py::list out;
                               for (const FrameStats& s : r.frame_stats())
                                 out.append(frame_stats_dict(s));
                               return out;
                             })
      .def_property_readonly("stats",
                             [](const Reconstruction& r) {
                               // The counts on the device the frames run on (no copy of the map).
                               py::dict d;
                               d["frames"] = r.frame_stats().size();
                               d["blocks_total"] = r.blocks_in_use();
                               d["blocks_per_level"] = r.blocks_per_level();
                               d["peak_blocks"] = r.peak_blocks();
                               d["dropped_blocks"] = r.dropped_blocks();
                               d["memory_bytes"] = r.map_memory_bytes();
                               const TrackingCounts& t = r.tracking_counts();
                               d["tracking"] =
                                   py::dict(py::arg("good") = t.good, py::arg("poor") = t.poor,
                                            py::arg("lost") = t.lost);
                               return d;
                             })
      .def_property_readonly("params", &Reconstruction::params)
      .def("__repr__", [](const Reconstruction& r) {
        return fmt::format("hivox.Reconstruction({} frames, {} blocks)", r.frame_stats().size(),
                           r.blocks_in_use());
      });

  m.def(
      "load_map",
      [](const std::filesystem::path& path, const ReconstructionParams& params,
         const std::optional<PinholeCamera>& camera, double depth_scale) {
        LoadedMap loaded = read_map_file(path, params.map);
        ReconstructionParams p = params;
        p.map.voxel_size_m = loaded.info.map.voxel_size_m;
        p.map.levels = loaded.info.map.levels;
        p.map.truncation_m = loaded.info.map.truncation_m;
        p.map.store_color = loaded.info.map.store_color;
        p.fusion.max_weight = loaded.info.fusion.max_weight;
        const PinholeCamera cam =
            camera ? *camera
            : loaded.info.session.camera
                ? *loaded.info.session.camera
                : throw Error(ErrorCode::InvalidArgument, path.string() +
                                                              ": no camera in the map file; "
                                                              "pass camera=");
        CameraRig rig = CameraRig::registered(cam);
        rig.depth_scale = depth_scale;
        return make_reconstruction(p, rig, std::move(loaded.map), loaded.info.session);
      },
      py::arg("path"), py::arg("params") = ReconstructionParams{}, py::arg("camera") = py::none(),
      py::arg("depth_scale") = 0.0,
      "Loads a map file into a Reconstruction that continues it (its voxel size, levels, "
      "truncation, colour and maximum weight are the file's; the camera the file's unless given).");

  m.def(
      "run",
      [](const std::shared_ptr<DatasetReader>& reader, const RunParams& params) {
        RunResult result;
        {
          py::gil_scoped_release release;
          result = run_reconstruction(*reader, params);
        }
        return py::make_tuple(std::move(result.reconstruction), summary_dict(result.summary));
      },
      py::arg("dataset"), py::arg("params") = RunParams{},
      "The whole run, as `hivox reconstruct` does it: returns (Reconstruction, summary dict).");
}

#include "hivox/io/intrinsics_io.h"

#include <algorithm>
#include <cmath>
#include <fstream>

#include <nlohmann/json.hpp>

#include "hivox/core/error.h"
#include "hivox/core/image.h"
#include "hivox/io/atomic_file.h"

namespace hivox {

namespace {

constexpr const char* kDistortionField = "distortion_k1k2p1p2k3";

double number_field(const nlohmann::json& j, const std::filesystem::path& path, const char* name) {
  if (!j.contains(name))
    fail(ErrorCode::InvalidData, "{}: missing field '{}'", path.string(), name);
  const auto& v = j.at(name);
  if (!v.is_number())
    fail(ErrorCode::InvalidData, "{}: field '{}' must be a number, found {}", path.string(), name,
         v.dump());
  return v.get<double>();
}

}  // namespace

IntrinsicsFile read_intrinsics_json(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) fail(ErrorCode::Io, "{}: cannot open intrinsics file", path.string());
  nlohmann::json j;
  try {
    in >> j;
  } catch (const nlohmann::json::exception& e) {
    fail(ErrorCode::InvalidData, "{}: not valid JSON ({})", path.string(), e.what());
  }
  if (!j.is_object()) fail(ErrorCode::InvalidData, "{}: expected a JSON object", path.string());
  IntrinsicsFile out;
  out.camera.fx = static_cast<float>(number_field(j, path, "fx"));
  out.camera.fy = static_cast<float>(number_field(j, path, "fy"));
  out.camera.cx = static_cast<float>(number_field(j, path, "cx"));
  out.camera.cy = static_cast<float>(number_field(j, path, "cy"));
  const double w = number_field(j, path, "width");
  const double h = number_field(j, path, "height");
  if (w != std::floor(w) || h != std::floor(h))
    fail(ErrorCode::InvalidData, "{}: width/height must be integers, found {} x {}", path.string(),
         w, h);
  if (!(w >= 1 && w <= kMaxImageSide && h >= 1 && h <= kMaxImageSide))
    fail(ErrorCode::InvalidData, "{}: width/height must be in [1, {}], found {} x {}",
         path.string(), kMaxImageSide, w, h);
  out.camera.width = static_cast<int>(w);
  out.camera.height = static_cast<int>(h);
  out.camera.validate(path.string());
  if (j.contains("depth_scale")) {
    out.depth_scale = number_field(j, path, "depth_scale");
    if (!(out.depth_scale > 0))
      fail(ErrorCode::InvalidArgument,
           "{}: depth_scale must be > 0 (raw units per metre, e.g. 5000 for TUM), got {}",
           path.string(), out.depth_scale);
  }
  if (j.contains("note") && j.at("note").is_string()) out.note = j.at("note").get<std::string>();
  if (j.contains(kDistortionField)) {
    const auto& d = j.at(kDistortionField);
    if (!d.is_array() || d.size() < 4 || d.size() > 5 ||
        !std::all_of(d.begin(), d.end(), [](const nlohmann::json& v) { return v.is_number(); }))
      fail(ErrorCode::InvalidData,
           "{}: field '{}' must be 4 or 5 numbers (k1 k2 p1 p2 [k3]), found {}", path.string(),
           kDistortionField, d.dump());
    out.distortion = {d[0].get<float>(), d[1].get<float>(), d[2].get<float>(), d[3].get<float>(),
                      d.size() == 5 ? d[4].get<float>() : 0.0f};
    out.distortion.validate(path.string());
  }
  if (j.contains("depth_noise")) {
    const auto& n = j.at("depth_noise");
    if (n == "kinect") {
      out.depth_noise = SensorNoise::kinect();
    } else if (n == "none") {
      out.depth_noise = SensorNoise::none();
    } else if (n.is_object() && n.size() == 3 && n.contains("sigma_min_m") &&
               n.contains("quadratic_per_m") && n.contains("z0_m") &&
               std::all_of(n.begin(), n.end(),
                           [](const nlohmann::json& v) { return v.is_number() && v >= 0; })) {
      out.depth_noise = SensorNoise{n["sigma_min_m"].get<float>(),
                                    n["quadratic_per_m"].get<float>(), n["z0_m"].get<float>()};
    } else {
      fail(ErrorCode::InvalidData,
           "{}: field 'depth_noise' must be \"kinect\", \"none\" or {{\"sigma_min_m\", "
           "\"quadratic_per_m\", \"z0_m\"}} (numbers >= 0), found {}",
           path.string(), n.dump());
    }
  }
  return out;
}

void write_intrinsics_json(const std::filesystem::path& path, const IntrinsicsFile& intrinsics) {
  nlohmann::json j;
  j["fx"] = intrinsics.camera.fx;
  j["fy"] = intrinsics.camera.fy;
  j["cx"] = intrinsics.camera.cx;
  j["cy"] = intrinsics.camera.cy;
  j["width"] = intrinsics.camera.width;
  j["height"] = intrinsics.camera.height;
  if (intrinsics.depth_scale > 0) j["depth_scale"] = intrinsics.depth_scale;
  if (!intrinsics.note.empty()) j["note"] = intrinsics.note;
  if (const auto& n = intrinsics.depth_noise) {
    const SensorNoise kinect = SensorNoise::kinect();
    if (n->sigma_min_m == 0 && n->quadratic_per_m == 0) {
      j["depth_noise"] = "none";
    } else if (n->sigma_min_m == kinect.sigma_min_m &&
               n->quadratic_per_m == kinect.quadratic_per_m && n->z0_m == kinect.z0_m) {
      j["depth_noise"] = "kinect";
    } else {
      j["depth_noise"] = {{"sigma_min_m", n->sigma_min_m},
                          {"quadratic_per_m", n->quadratic_per_m},
                          {"z0_m", n->z0_m}};
    }
  }
  if (!intrinsics.distortion.none()) {
    const LensDistortion& d = intrinsics.distortion;
    j[kDistortionField] = {d.k1, d.k2, d.p1, d.p2, d.k3};
  }
  AtomicFile file(path);
  std::ofstream out(file.temp_path());
  if (!out) fail(ErrorCode::Io, "{}: cannot open for writing", path.string());
  out << j.dump(2) << "\n";
  out.close();
  if (!out) fail(ErrorCode::Io, "{}: write failed", path.string());
  file.commit();
}

}  // namespace hivox

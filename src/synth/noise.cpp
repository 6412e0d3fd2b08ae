#include "hivox/synth/noise.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "core/parallel.h"
#include "hivox/core/error.h"

namespace hivox {

namespace {

constexpr double kHalfPi = 1.5707963267948966;

std::uint64_t mix64(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

/// Counter-based generator keyed by (seed, frame, pixel): draw k of a pixel is a hash of the key
/// and k, independent of the order in which pixels are processed and of which other draws are
/// made. Each effect owns fixed slots (see `Slot`), so switching one effect off leaves the
/// random numbers of the others unchanged.
class PixelRng {
 public:
  PixelRng(std::uint64_t seed, std::uint64_t frame, std::uint64_t pixel) {
    base_ = mix64(seed + 0x9E3779B97F4A7C15ull);
    base_ = mix64(base_ ^ (frame * 0xD1B54A32D192ED03ull + 0x8CB92BA72F3D8DD7ull));
    base_ = mix64(base_ ^ (pixel * 0xABC98388FB8FAC03ull + 0x632BE59BD9B4E019ull));
  }
  /// Uniform in [0, 1).
  double uniform(int slot) const {
    const std::uint64_t z =
        mix64(base_ + (static_cast<std::uint64_t>(slot) + 1) * 0x9E3779B97F4A7C15ull);
    return static_cast<double>(z >> 11) * (1.0 / 9007199254740992.0);
  }
  /// Two independent standard normal values from slots `slot` and `slot + 1` (Box-Muller).
  void gaussian2(int slot, double* a, double* b) const {
    const double u1 = 1.0 - uniform(slot);  // (0, 1]
    const double u2 = uniform(slot + 1);
    const double r = std::sqrt(-2.0 * std::log(u1));
    *a = r * std::cos(2.0 * std::numbers::pi * u2);
    *b = r * std::sin(2.0 * std::numbers::pi * u2);
  }

 private:
  std::uint64_t base_;
};

enum Slot { kDropout = 0, kLateral = 1 /* and 2 */, kEdge = 3, kAxial = 4 /* and 5 */ };

void require(bool ok, const char* field, double value, const char* rule) {
  if (!ok) fail(ErrorCode::InvalidArgument, "noise: {} must be {}, got {}", field, rule, value);
}

}  // namespace

double NoiseParams::axial_sigma_m(double z_m, double incidence_rad) const {
  const double dz = z_m - axial_sigma_offset_m;
  double sigma = axial_sigma_base_m + axial_sigma_quadratic_per_m * dz * dz;
  if (axial_sigma_angle_m > 0.0 && incidence_rad > 0.0 && z_m > 0.0) {
    const double theta = std::min(incidence_rad, kHalfPi - 1e-3);
    const double g = kHalfPi - theta;
    sigma += axial_sigma_angle_m * theta * theta / (std::sqrt(z_m) * g * g);
  }
  return sigma;
}

double NoiseParams::depth_step_m(double z_m) const {
  if (!(disparity_step_px > 0.0)) return 0.0;
  return disparity_step_px * z_m * z_m / (baseline_m * disparity_focal_px);
}

bool NoiseParams::enabled() const {
  return axial_sigma_base_m > 0.0 || axial_sigma_quadratic_per_m > 0.0 ||
         axial_sigma_angle_m > 0.0 || lateral_sigma_px > 0.0 || disparity_step_px > 0.0 ||
         max_incidence_rad < kHalfPi || min_depth_m > 0.0 || dropout_probability > 0.0 ||
         edge_dropout_probability > 0.0;
}

SensorNoise NoiseParams::sensor_noise() const {
  if (!enabled()) return SensorNoise::none();
  return {static_cast<float>(axial_sigma_base_m), static_cast<float>(axial_sigma_quadratic_per_m),
          static_cast<float>(axial_sigma_offset_m)};
}

void NoiseParams::validate() const {
  auto non_negative = [](double v) { return std::isfinite(v) && v >= 0.0; };
  auto probability = [](double v) { return std::isfinite(v) && v >= 0.0 && v <= 1.0; };
  require(non_negative(axial_sigma_base_m), "axial_sigma_base_m", axial_sigma_base_m, ">= 0");
  require(non_negative(axial_sigma_quadratic_per_m), "axial_sigma_quadratic_per_m",
          axial_sigma_quadratic_per_m, ">= 0");
  require(std::isfinite(axial_sigma_offset_m), "axial_sigma_offset_m", axial_sigma_offset_m,
          "finite");
  require(non_negative(axial_sigma_angle_m), "axial_sigma_angle_m", axial_sigma_angle_m, ">= 0");
  require(non_negative(lateral_sigma_px) && lateral_sigma_px <= 10.0, "lateral_sigma_px",
          lateral_sigma_px, "in [0, 10]");
  require(non_negative(disparity_step_px), "disparity_step_px", disparity_step_px, ">= 0");
  if (disparity_step_px > 0.0) {
    require(std::isfinite(baseline_m) && baseline_m > 0.0, "baseline_m", baseline_m,
            "> 0 when disparity_step_px > 0");
    require(std::isfinite(disparity_focal_px) && disparity_focal_px > 0.0, "disparity_focal_px",
            disparity_focal_px, "> 0 when disparity_step_px > 0");
  }
  require(
      std::isfinite(max_incidence_rad) && max_incidence_rad > 0.0 && max_incidence_rad <= kHalfPi,
      "max_incidence_rad", max_incidence_rad, "in (0, pi/2]");
  require(non_negative(min_depth_m), "min_depth_m", min_depth_m, ">= 0");
  require(probability(dropout_probability), "dropout_probability", dropout_probability,
          "in [0, 1]");
  require(probability(edge_dropout_probability), "edge_dropout_probability",
          edge_dropout_probability, "in [0, 1]");
  require(std::isfinite(edge_jump_fraction) && edge_jump_fraction > 0.0, "edge_jump_fraction",
          edge_jump_fraction, "> 0");
}

std::string NoiseParams::to_string() const {
  if (!enabled()) return "none";
  return fmt::format(
      "axial sigma = {} + {} (z - {})^2 + {} theta^2/(sqrt(z)(pi/2-theta)^2) m, lateral {} px, "
      "disparity step {} px at b*f = {} m x {} px, max incidence {:.1f} deg, min depth {} m, "
      "dropout {}, edge dropout {} (jump {}), seed {}",
      axial_sigma_base_m, axial_sigma_quadratic_per_m, axial_sigma_offset_m, axial_sigma_angle_m,
      lateral_sigma_px, disparity_step_px, baseline_m, disparity_focal_px,
      max_incidence_rad * 180.0 / 3.141592653589793, min_depth_m, dropout_probability,
      edge_dropout_probability, edge_jump_fraction, seed);
}

NoiseParams NoiseParams::none() {
  NoiseParams p;
  p.axial_sigma_base_m = 0;
  p.axial_sigma_quadratic_per_m = 0;
  p.axial_sigma_angle_m = 0;
  p.lateral_sigma_px = 0;
  p.disparity_step_px = 0;
  p.max_incidence_rad = kHalfPi;
  p.min_depth_m = 0;
  p.dropout_probability = 0;
  p.edge_dropout_probability = 0;
  return p;
}

std::vector<std::string> noise_preset_names() {
  return {"kinect", "none"};
}

NoiseParams noise_preset(std::string_view name) {
  if (name == "kinect") return NoiseParams::kinect();
  if (name == "none") return NoiseParams::none();
  fail(ErrorCode::InvalidArgument, "unknown noise preset '{}'; valid names: {}", name,
       fmt::join(noise_preset_names(), ", "));
}

DepthImage apply_noise(const RenderedFrame& clean, const PinholeCamera& camera,
                       const NoiseParams& params, std::uint64_t frame_index) {
  params.validate();
  const DepthImage& depth = clean.depth_m;
  if (depth.width() != camera.width || depth.height() != camera.height ||
      clean.normal_w.width() != depth.width() || clean.normal_w.height() != depth.height())
    fail(ErrorCode::InvalidArgument,
         "apply_noise: camera is {}x{} but the rendered depth is {}x{} and normals {}x{}",
         camera.width, camera.height, depth.width(), depth.height(), clean.normal_w.width(),
         clean.normal_w.height());
  if (!params.enabled()) return depth;

  const int w = depth.width(), h = depth.height();
  DepthImage out(w, h, 0.0f);
  const Eigen::Matrix3d R_wc = clean.T_wc.linear();
  const double cos_max = std::cos(params.max_incidence_rad);
  const double bf = params.baseline_m * params.disparity_focal_px;
  const double step = params.disparity_step_px;

  auto on_edge = [&](int x, int y, double z) {
    const double jump = params.edge_jump_fraction * z;
    constexpr int kDx[4] = {1, -1, 0, 0}, kDy[4] = {0, 0, 1, -1};
    for (int k = 0; k < 4; ++k) {
      const int nx = x + kDx[k], ny = y + kDy[k];
      if (!depth.inside(nx, ny)) continue;
      const double zn = depth(nx, ny);
      if (zn <= 0.0 || std::abs(zn - z) > jump) return true;
    }
    return false;
  };

  parallel_for(h, [&](int64_t row) {
    const int y = static_cast<int>(row);
    for (int x = 0; x < w; ++x) {
      const PixelRng rng(params.seed, frame_index, static_cast<std::uint64_t>(y) * w + x);
      if (params.dropout_probability > 0.0 && rng.uniform(kDropout) < params.dropout_probability)
        continue;
      double gx = 0, gy = 0;
      if (params.lateral_sigma_px > 0.0) rng.gaussian2(kLateral, &gx, &gy);
      const int sx =
          std::clamp(static_cast<int>(std::lround(x + params.lateral_sigma_px * gx)), 0, w - 1);
      const int sy =
          std::clamp(static_cast<int>(std::lround(y + params.lateral_sigma_px * gy)), 0, h - 1);
      const double z = depth(sx, sy);
      if (!(z > 0.0) || z < params.min_depth_m) continue;

      const Vec3f nf = clean.normal_w(sx, sy);
      const Eigen::Vector3d ray_w =
          (R_wc * Eigen::Vector3d((sx - camera.cx) / camera.fx, (sy - camera.cy) / camera.fy, 1.0))
              .normalized();
      const double cos_incidence =
          std::clamp(-(ray_w.x() * nf.x + ray_w.y() * nf.y + ray_w.z() * nf.z), -1.0, 1.0);
      if (cos_incidence < cos_max) continue;
      if (params.edge_dropout_probability > 0.0 &&
          rng.uniform(kEdge) < params.edge_dropout_probability && on_edge(sx, sy, z))
        continue;
      double g_axial, g_unused;
      rng.gaussian2(kAxial, &g_axial, &g_unused);

      const double sigma = params.axial_sigma_m(z, std::acos(cos_incidence));
      const double step_z = params.depth_step_m(z);
      const double sigma_gauss = std::sqrt(std::max(0.0, sigma * sigma - step_z * step_z / 12.0));
      double z_noisy = z + sigma_gauss * g_axial;
      if (step > 0.0) {
        if (!(z_noisy > 0.0)) continue;
        const double level = std::round(bf / (z_noisy * step));
        if (level < 1.0) continue;  // beyond the farthest representable disparity
        z_noisy = bf / (level * step);
      }
      if (!(z_noisy > 0.0)) continue;
      out(x, y) = static_cast<float>(z_noisy);
    }
  });
  return out;
}

}  // namespace hivox

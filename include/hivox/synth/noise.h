#pragma once
/// @file
/// Kinect-like depth noise for synthetic frames, after Nguyen, Izadi, Lovell, "Modeling Kinect
/// Sensor Noise for Improved 3D Reconstruction and Tracking" (3DIMPVT 2012) and Khoshelham,
/// Elberink, "Accuracy and Resolution of Kinect Depth Data" (Sensors 2012).
///
/// Per pixel, in this order:
/// 1. dropout: invalid with probability `dropout_probability`;
/// 2. lateral noise: the clean depth is looked up at the pixel offset by a Gaussian of
///    `lateral_sigma_px` per axis, rounded to the nearest pixel (jagged depth edges);
/// 3. invalid when the looked-up depth is 0 or below `min_depth_m`, when the angle between the
///    viewing ray and the surface normal exceeds `max_incidence_rad`, or (with probability
///    `edge_dropout_probability`) when it lies on a depth discontinuity (a 4-neighbour differs by
///    more than `edge_jump_fraction` of its depth) — the ragged holes along Kinect object borders;
/// 4. axial noise: Gaussian, then disparity quantisation `z_q = b f / (step * round(b f / (z *
///    step)))` with `b f = baseline_m * disparity_focal_px` and `step = disparity_step_px`.
///    The Gaussian's sigma is chosen so that the *total* (Gaussian + quantisation, whose variance
///    is step_z^2 / 12) equals Nguyen's measured axial sigma
///      sigma_z(z, theta) = a + b (z - z0)^2 + c theta^2 / (sqrt(z) (pi/2 - theta)^2)
///    (z in metres, theta the incidence angle), which already contains the sensor's quantisation.
///
/// Random numbers come from a counter-based hash of (seed, frame index, pixel), so the result
/// is the same for a given seed and frame whatever the thread count.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "hivox/core/camera.h"
#include "hivox/core/image.h"
#include "hivox/core/sensor_noise.h"
#include "hivox/synth/render.h"

namespace hivox {

/// Defaults are the `kinect` preset (Kinect v1 / PrimeSense at 640x480).
struct NoiseParams {
  double axial_sigma_base_m = 0.0012;           ///< a: sigma_z at z = z0, metres
  double axial_sigma_quadratic_per_m = 0.0019;  ///< b: growth with (z - z0)^2, 1/metres
  double axial_sigma_offset_m = 0.4;            ///< z0, metres
  double axial_sigma_angle_m = 0.0001;          ///< c: grazing-angle term, metres^1.5
  double lateral_sigma_px = 0.8;                ///< per-axis pixel lookup jitter, pixels
  double baseline_m = 0.075;                    ///< projector-camera baseline b, metres
  /// Focal length f of the sensor's disparity image (Kinect IR camera ~580 px), pixels. The
  /// quantisation belongs to the sensor, so it does not change with the output image size.
  double disparity_focal_px = 580.0;
  double disparity_step_px = 0.125;       ///< disparity quantum (1/8 pixel); 0 = no quantisation
  double max_incidence_rad = 1.3090;      ///< 75 deg: steeper surfaces return no depth
  double min_depth_m = 0.4;               ///< closer surfaces return no depth
  double dropout_probability = 0.001;     ///< random invalid pixels
  double edge_dropout_probability = 0.3;  ///< invalid pixels on depth discontinuities
  double edge_jump_fraction = 0.03;       ///< relative depth jump that marks a discontinuity
  std::uint64_t seed = 1;

  /// The modelled total axial standard deviation sigma_z(z, theta), metres.
  double axial_sigma_m(double z_m, double incidence_rad = 0.0) const;
  /// Depth difference between neighbouring disparity levels at depth z (0 without
  /// quantisation): step * z^2 / (b f), metres.
  double depth_step_m(double z_m) const;
  /// Whether any effect is on (false for the `none` preset).
  bool enabled() const;
  /// The axial noise model of a dataset rendered with these settings (what the refinement and
  /// tracking compare with): sigma(z) without the angle term, or none when nothing is on.
  SensorNoise sensor_noise() const;

  /// Throws `Error(InvalidArgument)` naming the first bad field.
  void validate() const;
  std::string to_string() const;

  static NoiseParams kinect() { return {}; }
  /// No effect at all: `apply_noise` returns the clean depth unchanged.
  static NoiseParams none();
};

/// Names accepted by `noise_preset`: "kinect", "none".
std::vector<std::string> noise_preset_names();
/// The named preset; throws `Error(InvalidArgument)` listing the names for an unknown one.
NoiseParams noise_preset(std::string_view name);

/// Noisy depth image (metres, 0 = invalid) from a clean render (its depth, world normals and
/// pose) and the camera it was rendered with. Deterministic for (params.seed, frame_index).
DepthImage apply_noise(const RenderedFrame& clean, const PinholeCamera& camera,
                       const NoiseParams& params, std::uint64_t frame_index);

}  // namespace hivox

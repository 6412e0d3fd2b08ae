// The built-in scenes. Sizes are those of a real office, in metres, world z up, floor at z = 0.

#include <cmath>
#include <cstdint>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "hivox/core/error.h"
#include "hivox/synth/scene.h"

namespace hivox {

namespace {

using Vec3 = Eigen::Vector3d;
constexpr double kPi = 3.141592653589793;

Eigen::Matrix3d yaw(double angle_rad) {
  return Eigen::AngleAxisd(angle_rad, Vec3::UnitZ()).toRotationMatrix();
}

Material plain(float r, float g, float b) {
  Material m;
  m.albedo = {r, g, b};
  return m;
}

Material textured(Texture texture, Eigen::Vector3f a, Eigen::Vector3f b, double period_m,
                  Vec3 stripe_axis_w = Vec3::UnitX()) {
  Material m;
  m.texture = texture;
  m.albedo = a;
  m.albedo2 = b;
  m.texture_period_m = period_m;
  m.stripe_axis_w = stripe_axis_w.normalized();
  return m;
}

/// Deterministic value in [0, 1) from an integer (splitmix64), identical on every platform.
double hash01(std::uint64_t i) {
  std::uint64_t z = i + 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return static_cast<double>(z >> 11) * (1.0 / 9007199254740992.0);
}

// ---- Building blocks ---------------------------------------------------------------------------

constexpr double kTableHeight = 0.75;
const Vec3 kTableCenterXy(0.0, 0.6, 0.0);

/// Room 4.0 x 3.2 x 2.5 m: walls and ceiling from a `Room`, the floor a plane at z = 0 (the
/// room's own floor sits 5 cm lower, hidden, so the floor can carry its own texture and label).
void add_room(SyntheticScene& scene) {
  scene.add(
      Room{Vec3(-2.0, -2.0, -0.05), Vec3(2.0, 1.2, 2.5)},
      textured(Texture::Stripes, {0.86f, 0.84f, 0.78f}, {0.74f, 0.76f, 0.80f}, 0.2, Vec3(1, 1, 0)),
      "wall");
  scene.add(Plane{Vec3::Zero(), Vec3::UnitZ()},
            textured(Texture::Checker, {0.58f, 0.45f, 0.32f}, {0.42f, 0.32f, 0.22f}, 0.3), "floor");
  Aabb content;
  content.extend(Vec3(-2.0, -2.0, 0.0));
  content.extend(Vec3(2.0, 1.2, 2.5));
  scene.set_content_bounds(content);
}

/// Table 1.4 x 0.7 m, top surface at 0.75 m (3 cm thick), four 4 x 4 cm legs.
void add_table(SyntheticScene& scene) {
  const Vec3 c = kTableCenterXy;
  scene.add(Box{Vec3(c.x(), c.y(), kTableHeight - 0.015), Vec3(0.7, 0.35, 0.015),
                Eigen::Matrix3d::Identity(), 0.004},
            textured(Texture::Stripes, {0.70f, 0.55f, 0.38f}, {0.64f, 0.49f, 0.33f}, 0.03),
            "table");
  for (double sx : {-1.0, 1.0})
    for (double sy : {-1.0, 1.0})
      scene.add(Box{Vec3(c.x() + sx * 0.64, c.y() + sy * 0.29, 0.36), Vec3(0.02, 0.02, 0.36)},
                plain(0.25f, 0.25f, 0.27f), "table_leg");
}

/// Keyboard 45 x 15 cm: a 15 mm base with rounded corners and 6 rows of 22 keys on a 19 mm
/// pitch (15 mm caps, 4 mm gaps, 8 mm high), a 7-wide space bar and 2-wide shift keys.
/// `bottom_center_w` is the centre of the base's underside.
void add_keyboard(SyntheticScene& scene, const Vec3& bottom_center_w, double yaw_rad) {
  const Eigen::Matrix3d R = yaw(yaw_rad);
  constexpr double kBaseHalfHeight = 0.0075, kPitch = 0.019, kGap = 0.004, kKeyHalfHeight = 0.004;
  constexpr int kRows = 6, kCols = 22;
  const Material base_material = plain(0.16f, 0.16f, 0.18f);
  const Material key_material = textured(Texture::Stripes, {0.82f, 0.82f, 0.80f},
                                         {0.74f, 0.74f, 0.72f}, 0.004, Vec3::UnitY());
  const Material accent = plain(0.80f, 0.25f, 0.20f);
  scene.add(Box{bottom_center_w + Vec3(0, 0, kBaseHalfHeight), Vec3(0.225, 0.075, kBaseHalfHeight),
                R, 0.004},
            base_material, "keyboard");
  const double key_z = 2 * kBaseHalfHeight + kKeyHalfHeight;
  auto add_key = [&](int row, int col, int width_keys, const Material& m) {
    // Key centre in keyboard coordinates (x along the rows, y away from the user).
    const double x = (col + 0.5 * width_keys - 0.5 * kCols) * kPitch;
    const double y = (row + 0.5 - 0.5 * kRows) * kPitch;
    const double half_x = 0.5 * (width_keys * kPitch - kGap);
    scene.add(Box{bottom_center_w + R * Vec3(x, y, key_z),
                  Vec3(half_x, 0.5 * (kPitch - kGap), kKeyHalfHeight), R, 0.0015},
              m, "keyboard");
  };
  for (int row = 0; row < kRows; ++row) {
    int col = 0;
    while (col < kCols) {
      int width = 1;
      if (row == 0 && col == 7) width = 7;                        // space bar
      if (row == 1 && (col == 0 || col == kCols - 2)) width = 2;  // shift keys
      const bool escape = row == kRows - 1 && col == 0;
      add_key(row, col, width, escape ? accent : key_material);
      col += width;
    }
  }
}

/// Bumpy blob: a core sphere of radius 7.5 cm and 90 bumps of radius 1-4 cm spread evenly over
/// it (Fibonacci directions, deterministic radii), each protruding by 0.5-0.8 of its radius.
/// Placed so that its lowest point is `sink_m` below `bottom_w.z()`, centred over `bottom_w`.
void add_blob(SyntheticScene& scene, const Vec3& bottom_w, double sink_m) {
  constexpr double kCore = 0.075;
  constexpr int kBumps = 90;
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  std::vector<Sphere> spheres;
  spheres.push_back({Vec3::Zero(), kCore});
  for (int i = 0; i < kBumps; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / kBumps;
    const double rho = std::sqrt(1.0 - z * z);
    const double phi = golden * i + 0.4 * hash01(3 * i);
    const Vec3 dir(rho * std::cos(phi), rho * std::sin(phi), z);
    const double r = 0.01 + 0.03 * hash01(3 * i + 1);
    const double out = kCore + r * (0.5 + 0.3 * hash01(3 * i + 2)) - r;  // protrudes 0.5-0.8 r
    spheres.push_back({dir * out, r});
  }
  double lowest = 0.0;
  for (const Sphere& s : spheres) lowest = std::min(lowest, s.center_w.z() - s.radius_m);
  const Vec3 shift = bottom_w - Vec3(0, 0, lowest + sink_m);
  const Material m = textured(Texture::Stripes, {0.85f, 0.45f, 0.20f}, {0.75f, 0.30f, 0.15f}, 0.012,
                              Vec3(0.3, 0.2, 1.0));
  for (Sphere s : spheres) {
    s.center_w += shift;
    scene.add(s, m, "blob");
  }
}

/// The room and table shared by `room` and `desk`, with the arc in front of the table.
void add_office(SyntheticScene& scene) {
  add_room(scene);
  add_table(scene);
  CameraPath path;
  path.kind = PathKind::Arc;
  path.target_w = Vec3(0.0, 0.55, 0.80);
  // Eye 1.2 m in front of the target (towards -y) at 1.45 m height: ~1.37 m away, 29 deg down.
  path.distance_m = std::hypot(1.2, 0.65);
  path.azimuth_rad = -0.5 * kPi;
  path.sweep_rad = 0.52;
  path.elevation_rad = std::atan2(0.65, 1.2);
  path.elevation_swing_rad = 0.05;
  path.distance_swing = 0.04;
  path.target_wobble_m = 0.03;
  scene.set_camera_path(path);
}

CameraPath orbit(double distance_m, double elevation_rad, double swing_rad) {
  CameraPath path;
  path.kind = PathKind::Orbit;
  path.target_w = Vec3::Zero();
  path.distance_m = distance_m;
  path.azimuth_rad = -0.5 * kPi;
  path.elevation_rad = elevation_rad;
  path.elevation_swing_rad = swing_rad;
  path.distance_swing = 0.05;
  path.target_wobble_m = 0.0;
  return path;
}

SyntheticScene make_room() {
  SyntheticScene scene("room");
  add_office(scene);
  return scene;
}

SyntheticScene make_box() {
  SyntheticScene scene("box");
  scene.add(Box{Vec3::Zero(), Vec3(0.15, 0.10, 0.08), yaw(0.0), 0.01},
            textured(Texture::Checker, {0.80f, 0.62f, 0.35f}, {0.55f, 0.38f, 0.20f}, 0.05), "box");
  scene.set_camera_path(orbit(0.75, 0.15, 0.65));
  return scene;
}

SyntheticScene make_spheres() {
  SyntheticScene scene("spheres");
  // Disjoint (gaps >= 1 cm), so the SDF is exact inside the solids as well.
  scene.add(
      Sphere{Vec3(0.0, 0.0, 0.0), 0.12},
      textured(Texture::Stripes, {0.20f, 0.45f, 0.80f}, {0.85f, 0.85f, 0.90f}, 0.03, Vec3::UnitZ()),
      "sphere");
  scene.add(Sphere{Vec3(0.21, 0.06, -0.05), 0.07}, plain(0.85f, 0.25f, 0.20f), "sphere");
  scene.add(Sphere{Vec3(-0.19, 0.09, 0.06), 0.06}, plain(0.25f, 0.70f, 0.30f), "sphere");
  scene.add(Sphere{Vec3(0.05, -0.19, 0.07), 0.045}, plain(0.90f, 0.80f, 0.25f), "sphere");
  scene.add(Sphere{Vec3(-0.06, 0.12, -0.16), 0.03}, plain(0.70f, 0.40f, 0.80f), "sphere");
  scene.set_camera_path(orbit(0.8, 0.15, 0.65));
  return scene;
}

SyntheticScene make_keyboard() {
  SyntheticScene scene("keyboard");
  add_keyboard(scene, Vec3(0, 0, -0.0115), 0.0);
  scene.set_camera_path(orbit(0.75, 0.2, 0.75));
  return scene;
}

SyntheticScene make_blob() {
  SyntheticScene scene("blob");
  add_blob(scene, Vec3(0, 0, -0.1), 0.0);
  Aabb b = scene.content_bounds();
  const Vec3 c = b.center();
  CameraPath path = orbit(0.6, 0.15, 0.7);
  path.target_w = c;
  scene.set_camera_path(path);
  return scene;
}

SyntheticScene make_desk() {
  SyntheticScene scene("desk");
  add_office(scene);
  const double top = kTableHeight;
  add_keyboard(scene, Vec3(0.0, 0.45, top), 0.0);
  // Blob resting on the table, sunk 2 mm so that it stands on a small contact patch.
  add_blob(scene, Vec3(0.45, 0.58, top), 0.002);
  // Cardboard box, turned 25 degrees.
  scene.add(Box{Vec3(-0.47, 0.62, top + 0.06), Vec3(0.12, 0.09, 0.06), yaw(0.44), 0.006},
            textured(Texture::Checker, {0.80f, 0.62f, 0.35f}, {0.60f, 0.42f, 0.22f}, 0.04), "box");
  // Monitor: screen, stand and foot.
  scene.add(Box{Vec3(0.0, 0.84, top + 0.27), Vec3(0.28, 0.015, 0.17), yaw(0.0), 0.008},
            plain(0.10f, 0.10f, 0.12f), "monitor");
  scene.add(Cylinder{Vec3(0.0, 0.86, top + 0.055), Vec3::UnitZ(), 0.02, 0.045},
            plain(0.30f, 0.30f, 0.32f), "monitor");
  scene.add(Box{Vec3(0.0, 0.86, top + 0.005), Vec3(0.10, 0.07, 0.005), yaw(0.0), 0.003},
            plain(0.30f, 0.30f, 0.32f), "monitor");
  // Mug (closed cylinder) and an orange on the table; two balls on the floor.
  scene.add(Cylinder{Vec3(0.28, 0.80, top + 0.05), Vec3::UnitZ(), 0.04, 0.05},
            textured(Texture::Stripes, {0.92f, 0.92f, 0.90f}, {0.20f, 0.35f, 0.75f}, 0.015,
                     Vec3::UnitZ()),
            "mug");
  scene.add(Sphere{Vec3(-0.30, 0.33, top + 0.04), 0.04}, plain(0.95f, 0.55f, 0.10f), "sphere");
  scene.add(
      Sphere{Vec3(0.95, 0.05, 0.11), 0.11},
      textured(Texture::Stripes, {0.85f, 0.20f, 0.20f}, {0.95f, 0.90f, 0.85f}, 0.05, Vec3::UnitZ()),
      "sphere");
  scene.add(Sphere{Vec3(-1.00, 0.40, 0.08), 0.08}, plain(0.25f, 0.55f, 0.85f), "sphere");
  return scene;
}

}  // namespace

std::vector<std::string> scene_names() {
  return {"room", "box", "spheres", "keyboard", "blob", "desk"};
}

SyntheticScene make_scene(std::string_view name) {
  if (name == "room") return make_room();
  if (name == "box") return make_box();
  if (name == "spheres") return make_spheres();
  if (name == "keyboard") return make_keyboard();
  if (name == "blob") return make_blob();
  if (name == "desk") return make_desk();
  fail(ErrorCode::InvalidArgument, "unknown synthetic scene '{}'; valid names: {}", name,
       fmt::join(scene_names(), ", "));
}

}  // namespace hivox

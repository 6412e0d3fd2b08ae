// `hivox synth --mesh` as a user meets it: a sequence rendered from a mesh along a trajectory or
// an orbit, read back from disk, and one-line errors for every bad input.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "apps/cli_util.h"
#include "hivox/io/image_io.h"
#include "hivox/io/intrinsics_io.h"
#include "hivox/io/mesh_file.h"
#include "hivox/io/trajectory_io.h"
#include "synth/mesh_shapes.h"
#include "test_util.h"

namespace hivox {
namespace {

namespace fs = std::filesystem;
using test::CliRun;
using test::contains;
using test::run_hivox;
using Vec3 = Eigen::Vector3d;

// A unit cube on the floor (z from 0 to 1), six poses around it, an 80x60 camera.
struct MeshInput {
  test::TempDir dir;
  std::string mesh = (dir / "cube.off").string();
  std::string trajectory = (dir / "groundtruth.txt").string();
  std::string intrinsics = (dir / "intrinsics.json").string();
  PinholeCamera camera{70.f, 70.f, 39.5f, 29.5f, 80, 60};
  std::vector<StampedPose> poses;

  MeshInput() {
    std::string off = "OFF\n8 12 0\n";
    for (int i = 0; i < 8; ++i)
      off += fmt::format("{} {} {}\n", (i & 1) ? 0.5 : -0.5, (i & 2) ? 0.5 : -0.5, (i & 4) ? 1 : 0);
    for (const auto& t : test::box_mesh(Vec3::Zero(), Vec3::Ones()).triangles)
      off += fmt::format("3 {} {} {}\n", t[0], t[1], t[2]);
    test::write_text(mesh, off);
    for (int i = 0; i < 6; ++i) {
      const double a = 0.4 * i;
      poses.push_back({0.1 * i, look_at(Vec3(2.5 * std::cos(a), 2.5 * std::sin(a), 1.5),
                                        Vec3(0, 0, 0.5), Vec3::UnitZ())});
    }
    write_tum_trajectory(trajectory, poses);
    IntrinsicsFile file;
    file.camera = camera;
    file.depth_scale = 1000;
    write_intrinsics_json(intrinsics, file);
  }
  std::string args() const {
    return "synth --mesh " + mesh + " --trajectory " + trajectory + " --intrinsics " + intrinsics;
  }
};

TEST(SynthMeshCli, TrajectoryRenderIsTheMeshAtThePoses) {
  const MeshInput in;
  const std::string out = (in.dir / "seq").string();
  const CliRun r = run_hivox(in.args() + " --stride 2 --noise none --out " + out);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "12 triangles")) << r.output;

  const std::vector<StampedPose> gt = read_tum_trajectory(fs::path(out) / "groundtruth.txt");
  ASSERT_EQ(gt.size(), 3u);  // poses 0, 2, 4
  for (std::size_t i = 0; i < gt.size(); ++i) {
    EXPECT_NEAR(gt[i].timestamp_s, in.poses[2 * i].timestamp_s, 1e-6);
    EXPECT_TRUE(gt[i].T_wc.isApprox(in.poses[2 * i].T_wc, 1e-8));
  }
  // The file's depth scale and camera.
  const IntrinsicsFile intr = read_intrinsics_json(fs::path(out) / "intrinsics.json");
  EXPECT_EQ(intr.camera, in.camera);
  EXPECT_EQ(intr.depth_scale, 1000);
  // The reference mesh beside the frames.
  EXPECT_EQ(read_mesh(fs::path(out) / "mesh.ply").triangle_count(), 12);

  // Frame 1 (pose 2) against the exact ray-box intersection, to the PNG's 1 mm steps.
  const DepthImage depth =
      depth_to_metres(read_depth16(fs::path(out) / "depth" / "0.200000.png"), 1000);
  ASSERT_EQ(depth.width(), 80);
  const Pose& T = in.poses[2].T_wc;
  int checked = 0;
  for (int v = 0; v < 60; v += 3)
    for (int u = 0; u < 80; u += 3) {
      const Vec3 d = T.linear() * test::pixel_ray_c(in.camera, u, v);
      const auto inner =
          test::ray_box(T.translation(), d, Vec3(-0.499, -0.499, 0.001), Vec3(0.499, 0.499, 0.999));
      const auto outer = test::ray_box(T.translation(), d, Vec3(-0.501, -0.501, -0.001),
                                       Vec3(0.501, 0.501, 1.001));
      if (inner) {
        const auto exact =
            test::ray_box(T.translation(), d, Vec3(-0.5, -0.5, 0.0), Vec3(0.5, 0.5, 1.0));
        ASSERT_TRUE(exact);
        EXPECT_NEAR(depth(u, v), exact->t, 0.0006) << u << "," << v;  // 1 mm steps, rounded
        ++checked;
      } else if (!outer) {
        EXPECT_EQ(depth(u, v), 0.0f) << u << "," << v;
      }
    }
  EXPECT_GT(checked, 50);
  EXPECT_TRUE(fs::is_regular_file(fs::path(out) / "rgb" / "0.200000.png"));
}

TEST(SynthMeshCli, OrbitWritesTheFramesAsked) {
  const MeshInput in;
  const std::string out = (in.dir / "orbit").string();
  const CliRun r = run_hivox("synth --mesh " + in.mesh +
                             " --orbit --frames 4 --width 80 --height 60 --out " + out);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(read_tum_trajectory(fs::path(out) / "groundtruth.txt").size(), 4u);
  EXPECT_EQ(read_intrinsics_json(fs::path(out) / "intrinsics.json").camera.fx, 525.f / 8);

  // A model in millimetres seen as metres is refused with the way out.
  const CliRun big = run_hivox("synth --mesh " + in.mesh + " --orbit --mesh-scale 100 --out " +
                               (in.dir / "big").string());
  EXPECT_EQ(big.exit_code, 1) << big.output;
  EXPECT_TRUE(contains(big.output, "--mesh-scale")) << big.output;
  EXPECT_FALSE(fs::exists(in.dir / "big"));
}

TEST(SynthMeshCli, BadInputIsOneLineNamingIt) {
  const MeshInput in;
  const fs::path& d = in.dir.path();
  test::write_text(d / "points.off", "OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n");
  test::write_text(d / "bad_line.txt", "0.0 1 2 3\n");
  test::write_text(d / "backwards.txt",
                   "0.2 0 0 0 0 0 0 1\n0.1 0 0 0 0 0 0 1\n0.3 0 0 0 0 0 0 1\n");
  test::write_text(d / "cube.stl", "solid\n");
  const std::string out = " --out " + (d / "out").string();
  const std::string mesh = " --mesh " + in.mesh;
  const std::string traj = " --trajectory " + in.trajectory;
  const std::string intr = " --intrinsics " + in.intrinsics;
  struct Case {
    std::string args;
    int exit_code;  // 100: any CLI11 usage code (>= 100)
    std::vector<std::string> expected;
  };
  const std::vector<Case> cases = {
      {"synth --mesh /no/such/mesh.off" + traj + intr + out, 1, {"/no/such/mesh.off"}},
      {"synth --mesh " + (d / "points.off").string() + traj + intr + out,
       1,
       {"points.off", "no triangles"}},
      {"synth --mesh " + (d / "cube.stl").string() + traj + intr + out, 1, {"cube.stl"}},
      {"synth" + mesh + " --trajectory " + (d / "bad_line.txt").string() + intr + out,
       1,
       {"bad_line.txt"}},
      {"synth" + mesh + " --trajectory " + (d / "backwards.txt").string() + intr + out,
       1,
       {"backwards.txt", "order"}},
      {"synth" + mesh + " --trajectory /no/such/gt.txt" + intr + out, 1, {"/no/such/gt.txt"}},
      {"synth" + mesh + traj + " --intrinsics /no/such/intr.json" + out, 1, {"/no/such/intr.json"}},
      {"synth" + mesh + out, 1, {"--trajectory", "--orbit"}},
      {"synth" + mesh + traj + out, 1, {"--intrinsics"}},
      {"synth" + mesh + " --orbit --mesh-scale 0" + out, 1, {"--mesh-scale"}},
      {"synth --scene box" + mesh + " --orbit" + out, 100, {"--mesh"}},
      {"synth --scene box" + traj + intr + out, 100, {"--mesh"}},
      {"synth" + mesh + " --orbit" + traj + intr + out, 100, {"--trajectory"}},
      {"synth" + mesh + traj + intr + " --width 100" + out, 100, {"--intrinsics"}},
      {"synth" + mesh + " --orbit --stride 2" + out, 100, {"--trajectory"}},
      {"synth" + mesh + traj + intr + " --up y" + out, 100, {"--orbit"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.args);
    const CliRun r = run_hivox(c.args);
    if (c.exit_code == 100)
      EXPECT_GE(r.exit_code, 100) << r.output;
    else
      EXPECT_EQ(r.exit_code, c.exit_code) << r.output;
    for (const std::string& part : c.expected)
      EXPECT_TRUE(contains(r.output, part)) << "lacks '" << part << "':\n" << r.output;
    EXPECT_FALSE(contains(r.output, "unexpected failure")) << r.output;
    EXPECT_FALSE(fs::exists(d / "out"));
  }
}

}  // namespace
}  // namespace hivox

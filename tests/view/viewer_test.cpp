// The viewer's data: the binary mesh read back independently of the writer, decimation for
// display, and what load_viewer_content makes of a run folder, a mesh file and a map file (and
// its errors).

#include "hivox/view/viewer.h"

#include <gtest/gtest.h>

#include <cstring>

#include <nlohmann/json.hpp>

#include "hivox/core/error.h"
#include "hivox/io/map_file.h"
#include "hivox/io/ply.h"
#include "hivox/mesh/extract_mesh.h"
#include "hivox/run/runner.h"
#include "hivox/synth/synthetic_dataset.h"
#include "mesh_test_util.h"
#include "test_util.h"
#include "view/http_client.h"

namespace hivox {
namespace {

using json = nlohmann::json;

/// A w x h grid of unit squares (two triangles each) in the z = 0 plane, `cell` metres apart,
/// with colours, normals and the level of the row's parity.
TriangleMesh grid(int w, int h, float cell) {
  TriangleMesh m = test::plane_mesh(w, h, cell);
  for (int y = 0; y <= h; ++y)
    for (int x = 0; x <= w; ++x) {
      m.normals_w.push_back({0, 0, 1});
      m.colors.push_back({static_cast<uint8_t>(x), static_cast<uint8_t>(y), 7});
      m.levels.push_back(static_cast<uint8_t>(y % 2));
    }
  return m;
}

template <typename T>
T read_at(const std::string& bytes, std::size_t offset) {
  T value;
  std::memcpy(&value, bytes.data() + offset, sizeof value);
  return value;
}

TEST(Viewer, BinaryMeshHoldsEveryAttributeAtItsDocumentedPlace) {
  const TriangleMesh m = grid(3, 2, 0.5f);  // 12 vertices, 12 triangles
  const std::string b = mesh_to_binary(m);
  ASSERT_EQ(b.substr(0, 8), "HVXMESH1");
  const uint32_t nv = read_at<uint32_t>(b, 8), nt = read_at<uint32_t>(b, 12),
                 flags = read_at<uint32_t>(b, 16);
  EXPECT_EQ(nv, 12u);
  EXPECT_EQ(nt, 12u);
  EXPECT_EQ(flags, 7u);
  std::size_t at = 24;
  for (uint32_t v = 0; v < nv; ++v)
    for (int a = 0; a < 3; ++a)
      EXPECT_EQ(read_at<float>(b, at + 4 * (3 * v + a)), m.positions_w[v][a]);
  at += 12 * nv;
  EXPECT_EQ(read_at<float>(b, at + 8), 1.0f);  // first normal's z
  at += 12 * nv;
  for (uint32_t v = 0; v < nv; ++v) {
    EXPECT_EQ(static_cast<uint8_t>(b[at + 3 * v]), m.colors[v].r);
    EXPECT_EQ(static_cast<uint8_t>(b[at + 3 * v + 1]), m.colors[v].g);
  }
  at += (3 * nv + 3) / 4 * 4;  // 36 bytes: already aligned
  for (uint32_t v = 0; v < nv; ++v) EXPECT_EQ(static_cast<uint8_t>(b[at + v]), m.levels[v]);
  at += (nv + 3) / 4 * 4;
  for (uint32_t t = 0; t < nt; ++t)
    for (int k = 0; k < 3; ++k)
      EXPECT_EQ(read_at<uint32_t>(b, at + 4 * (3 * t + k)),
                static_cast<uint32_t>(m.triangles[t][k]));
  EXPECT_EQ(b.size(), at + 12 * nt);
  // Without normals and with 5 vertices: colours (15 B) and levels (5 B) are padded to 4.
  TriangleMesh small = grid(4, 1, 1.0f);
  small.normals_w.clear();
  const std::string s = mesh_to_binary(small);
  EXPECT_EQ(read_at<uint32_t>(s, 16), 6u);
  const std::size_t v = 10;
  EXPECT_EQ(s.size(), 24 + 12 * v + 32 + 12 + 12 * small.triangles.size());
}

TEST(Viewer, DecimationKeepsTheShapeWithinTheLimit) {
  const TriangleMesh m = grid(200, 100, 0.01f);  // 40 000 triangles over 2 x 1 m
  EXPECT_EQ(decimate_for_display(m, 40000).triangle_count(), 40000);  // within: unchanged
  const TriangleMesh d = decimate_for_display(m, 5000);
  EXPECT_LE(d.triangle_count(), 5000);
  EXPECT_GT(d.triangle_count(), 1000);  // not far below the limit
  d.validate();
  float max_x = 0, max_y = 0;
  for (const Vec3f& p : d.positions_w) {
    EXPECT_EQ(p.z, 0.0f);
    max_x = std::max(max_x, p.x);
    max_y = std::max(max_y, p.y);
  }
  EXPECT_GT(max_x, 1.9f);  // still spans the grid
  EXPECT_GT(max_y, 0.9f);
  for (const Vec3f& n : d.normals_w) EXPECT_NEAR(n.z, 1.0f, 1e-6f);
  for (uint8_t l : d.levels) EXPECT_LE(l, 1);
}

TEST(Viewer, LoadsARunFolderAMeshAndAMapAndServesThem) {
  test::TempDir dir;
  SyntheticDataset data(
      parse_synthetic_spec("synthetic:desk?frames=300&noise=none&width=160&height=120"));
  RunParams p;
  p.reconstruction.map.levels = 2;
  p.reconstruction.map.voxel_size_m = 0.01f;
  p.reconstruction.map.truncation_m = 0.04f;
  p.max_frames = 6;
  p.poses = PoseSpec::parse("gt");
  p.out_dir = dir / "run";
  p.map_out = dir / "map.hvx";
  const RunResult run = run_reconstruction(data, p);

  const ViewerContent folder = load_viewer_content(dir / "run", ViewerParams{});
  EXPECT_EQ(folder.kind, ViewerContent::Kind::RunFolder);
  EXPECT_EQ(folder.mesh.triangle_count(), run.summary.mesh_triangles);
  EXPECT_EQ(folder.trajectory.size(), 6u);
  EXPECT_EQ(folder.levels, 2);
  EXPECT_FLOAT_EQ(folder.voxel_size_m, 0.01f);
  EXPECT_FALSE(folder.images.empty());

  const ViewerContent map = load_viewer_content(dir / "map.hvx", ViewerParams{});
  EXPECT_EQ(map.kind, ViewerContent::Kind::MapFile);
  EXPECT_EQ(map.mesh.triangle_count(), run.summary.mesh_triangles);
  EXPECT_EQ(map.trajectory.size(), 1u);  // the last pose

  const ViewerContent mesh = load_viewer_content(dir / "run/mesh.ply", ViewerParams{});
  EXPECT_EQ(mesh.kind, ViewerContent::Kind::MeshFile);
  EXPECT_EQ(mesh.levels, 2);  // from the mesh's own levels
  EXPECT_TRUE(mesh.trajectory.empty());

  ViewServer server{ViewServerParams{}};
  serve_viewer(server, std::make_shared<const ViewerContent>(folder));
  server.start();
  const json info = json::parse(test::get(server.port(), "/api/info.json").body);
  EXPECT_EQ(info["triangles"], run.summary.mesh_triangles);
  EXPECT_EQ(info["kind"], "run folder");
  EXPECT_EQ(info["levels"], 2);
  EXPECT_EQ(info["voxel_sizes_mm"].size(), 2u);
  EXPECT_EQ(info["stats"]["frames"], 6);
  int64_t per_level = 0;
  for (const auto& n : info["vertices_per_level"]) per_level += n.get<int64_t>();
  EXPECT_EQ(per_level, folder.mesh.vertex_count());
  const auto mesh_bin = test::get(server.port(), "/api/mesh.bin");
  EXPECT_EQ(mesh_bin.header("Content-Type"), "application/octet-stream");
  EXPECT_EQ(mesh_bin.body, mesh_to_binary(folder.mesh));
  EXPECT_EQ(json::parse(test::get(server.port(), "/api/trajectory.json").body).size(), 6u);
  EXPECT_EQ(test::get(server.port(), "/files/stats.json").status, 200);
  EXPECT_EQ(test::get(server.port(), "/files/levels.png").header("Content-Type"), "image/png");
  EXPECT_EQ(test::get(server.port(), "/").header("Content-Type"), "text/html; charset=utf-8");
}

TEST(Viewer, ErrorsNameThePath) {
  test::TempDir dir;
  const auto expect_error = [](const std::filesystem::path& path, ErrorCode code,
                               const std::string& words) {
    try {
      load_viewer_content(path, ViewerParams{});
      ADD_FAILURE() << path << " was accepted";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), code) << e.what();
      EXPECT_TRUE(test::contains(e.what(), path.string())) << e.what();
      EXPECT_TRUE(test::contains(e.what(), words)) << e.what();
    }
  };
  expect_error(dir / "missing", ErrorCode::Io, "no such file");
  std::filesystem::create_directories(dir / "empty");
  expect_error(dir / "empty", ErrorCode::Io, "no mesh.ply");
  test::write_text(dir / "notes.txt", "hello");
  expect_error(dir / "notes.txt", ErrorCode::Unsupported, "also takes a run's output folder");
  test::write_text(dir / "points.obj", "v 0 0 0\nv 1 0 0\n");
  expect_error(dir / "points.obj", ErrorCode::InvalidData, "no triangles");
  test::write_text(dir / "bad.ply", "ply\nformat nonsense\n");
  expect_error(dir / "bad.ply", ErrorCode::InvalidData, "");
  ViewerParams p;
  p.max_triangles = 5;
  EXPECT_THROW(p.validate(), Error);
}

}  // namespace
}  // namespace hivox

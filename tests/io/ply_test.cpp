#include "hivox/io/ply.h"

#include <gtest/gtest.h>

#include <cstring>
#include <fstream>

#include "hivox/core/error.h"
#include "hivox/io/off.h"
#include "test_util.h"

namespace hivox {
namespace {

using test::TempDir;

TriangleMesh small_mesh() {
  TriangleMesh m;
  m.positions_w = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1.5f}};
  m.normals_w = {{0, 0, 1}, {0, 0, 1}, {0, 1, 0}, {1, 0, 0}};
  m.colors = {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}, {1, 2, 3}};
  m.levels = {0, 1, 2, 3};
  m.triangles = {{0, 1, 2}, {0, 2, 3}, {3, 1, 0}};
  return m;
}

void write_bytes(const std::filesystem::path& p, const std::string& s) {
  std::ofstream(p, std::ios::binary) << s;
}

TEST(Ply, BinaryRoundTripKeepsEverything) {
  TempDir dir;
  const TriangleMesh m = small_mesh();
  write_ply(dir / "m.ply", m);
  const TriangleMesh r = read_ply(dir / "m.ply");
  ASSERT_EQ(r.vertex_count(), 4);
  ASSERT_EQ(r.triangle_count(), 3);
  ASSERT_EQ(r.normals_w.size(), 4u);
  ASSERT_EQ(r.colors.size(), 4u);
  ASSERT_EQ(r.levels, m.levels);
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(r.positions_w[i].z, m.positions_w[i].z);
    EXPECT_EQ(r.normals_w[i].x, m.normals_w[i].x);
    EXPECT_EQ(r.colors[i], m.colors[i]);
  }
  EXPECT_EQ(r.triangles, m.triangles);
  // The header says what a viewer needs.
  std::ifstream in(dir / "m.ply", std::ios::binary);
  std::string header((std::istreambuf_iterator<char>(in)), {});
  header.resize(header.find("end_header"));
  EXPECT_TRUE(test::contains(header, "format binary_little_endian 1.0")) << header;
  EXPECT_TRUE(test::contains(header, "property uchar red")) << header;
  EXPECT_TRUE(test::contains(header, "property uchar level")) << header;
  EXPECT_TRUE(test::contains(header, "property list uchar int vertex_indices")) << header;
}

TEST(Ply, AbsentAttributesAreOmitted) {
  TempDir dir;
  TriangleMesh m = small_mesh();
  m.normals_w.clear();
  m.colors.clear();
  m.levels.clear();
  write_ply(dir / "m.ply", m);
  const TriangleMesh r = read_ply(dir / "m.ply");
  EXPECT_TRUE(r.normals_w.empty());
  EXPECT_TRUE(r.colors.empty());
  EXPECT_TRUE(r.levels.empty());
  EXPECT_EQ(r.triangles, m.triangles);
  // 12 bytes per vertex, 13 per triangle after the header.
  const auto size = std::filesystem::file_size(dir / "m.ply");
  std::ifstream in(dir / "m.ply", std::ios::binary);
  std::string all((std::istreambuf_iterator<char>(in)), {});
  const std::size_t body = all.size() - (all.find("end_header\n") + 11);
  EXPECT_EQ(body, 4u * 12u + 3u * 13u) << size;
}

TEST(Ply, InconsistentMeshIsNotWritten) {
  TempDir dir;
  TriangleMesh m = small_mesh();
  m.colors.pop_back();
  EXPECT_TRUE(test::contains(test::message_of([&] { write_ply(dir / "m.ply", m); }), "colors"));
  m = small_mesh();
  m.triangles.push_back({0, 1, 4});
  EXPECT_TRUE(test::contains(test::message_of([&] { write_ply(dir / "m.ply", m); }), "outside"));
  EXPECT_TRUE(test::contains(
      test::message_of([&] { write_ply(dir / "no/such/dir/m.ply", small_mesh()); }), "m.ply"));
}

TEST(Ply, AsciiWithExtraPropertiesAndPolygons) {
  TempDir dir;
  write_bytes(dir / "a.ply",
              "ply\r\nformat ascii 1.0\r\ncomment made by hand\r\n"
              "element vertex 5\r\n"
              "property double x\r\nproperty double y\r\nproperty double z\r\n"
              "property list uchar float junk\r\n"
              "property float red\r\nproperty float green\r\nproperty float blue\r\n"
              "property int quality\r\n"
              "element face 2\r\n"
              "property uchar flags\r\n"
              "property list uchar int vertex_indices\r\n"
              "property list int short more_junk\r\n"
              "element edge 1\r\nproperty int vertex1\r\nproperty int vertex2\r\n"
              "end_header\r\n"
              "0 0 0 2 9.5 9.5 1 0 0 7\r\n"
              "1 0 0 0 0 1 0 -3\r\n"
              "1 1 0 1 4 0 0 1 0\r\n"
              "0 1 0 0 0.5 0.5 0.5 0\n"
              "0.5 0.5 1e-1 0 0 0 0 0\n"
              "9 4 0 1 2 3 2 7 8\n"
              "0 3 2 3 4 0\n"
              "0 1\n");
  const TriangleMesh m = read_ply(dir / "a.ply");
  ASSERT_EQ(m.vertex_count(), 5);
  EXPECT_FLOAT_EQ(m.positions_w[4].z, 0.1f);
  ASSERT_EQ(m.colors.size(), 5u);
  EXPECT_EQ(m.colors[0], (Rgb8{255, 0, 0}));
  EXPECT_EQ(m.colors[3], (Rgb8{128, 128, 128}));
  EXPECT_TRUE(m.normals_w.empty());
  ASSERT_EQ(m.triangle_count(), 3);  // the quad is a fan of two
  EXPECT_EQ(m.triangles[0], (std::array<int32_t, 3>{0, 1, 2}));
  EXPECT_EQ(m.triangles[1], (std::array<int32_t, 3>{0, 2, 3}));
  EXPECT_EQ(m.triangles[2], (std::array<int32_t, 3>{2, 3, 4}));
}

TEST(Ply, BigEndianBinary) {
  TempDir dir;
  std::string s =
      "ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float x\n"
      "property float y\nproperty float z\nelement face 1\n"
      "property list uchar uint vertex_indices\nend_header\n";
  auto put_be = [&](auto v) {
    char b[sizeof(v)];
    std::memcpy(b, &v, sizeof(v));
    for (int i = static_cast<int>(sizeof(v)) - 1; i >= 0; --i) s.push_back(b[i]);
  };
  for (const float v : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 2.f, 0.f}) put_be(v);
  s.push_back(3);
  for (const uint32_t i : {0u, 1u, 2u}) put_be(i);
  write_bytes(dir / "be.ply", s);
  const TriangleMesh m = read_ply(dir / "be.ply");
  ASSERT_EQ(m.vertex_count(), 3);
  EXPECT_EQ(m.positions_w[2].y, 2.0f);
  EXPECT_EQ(m.triangles[0], (std::array<int32_t, 3>{0, 1, 2}));
}

TEST(Ply, MalformedFilesAreOneLineErrorsNamingTheFile) {
  TempDir dir;
  const std::string good_header =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
  const struct {
    const char* name;
    std::string text;
    const char* expect;
  } cases[] = {
      {"notply.ply", "hello\n", "not a PLY"},
      {"noformat.ply", "ply\nelement vertex 0\nend_header\n", "format"},
      {"badformat.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n", "middle"},
      {"badtype.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n",
       "malformed property"},
      {"noend.ply", "ply\nformat ascii 1.0\nelement vertex 0\n", "end_header"},
      {"noxyz.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n",
       "x, y or z"},
      {"short.ply", good_header + "0 0 0\n1 0 0\n0 1 0\n3 0 1\n", "ends inside face 0"},
      {"range.ply", good_header + "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", "index 3"},
      {"line.ply", good_header + "0 0 0\n1 0 0\n0 1 0\n2 0 1\n", "2 corners"},
      {"nan.ply", good_header + "0 0 zero\n1 0 0\n0 1 0\n3 0 1 2\n", "'zero'"},
      {"corners.ply", good_header + "0 0 0\n1 0 0\n0 1 0\n255 0 1 2\n", "255 corners"},
      {"list.ply",
       "ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\n"
       "property float y\nproperty float z\nelement face 1\n"
       "property list uint int vertex_indices\nend_header\n\xff\xff\xff\x7f",
       "2147483647 corners"},
      {"nanindex.ply",
       "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
       "property float z\nelement face 1\nproperty list uchar float vertex_indices\n"
       "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 nan\n",
       "index nan"},
      {"huge.ply",
       "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000\nproperty float x\n"
       "property float y\nproperty float z\nend_header\n",
       "more elements"},
  };
  for (const auto& c : cases) {
    write_bytes(dir / c.name, c.text);
    const std::string e = test::message_of([&] { read_ply(dir / c.name); });
    EXPECT_TRUE(test::contains(e, c.name)) << c.name << ": " << e;
    EXPECT_TRUE(test::contains(e, c.expect)) << c.name << ": " << e;
    EXPECT_FALSE(test::contains(e, "\n")) << e;
  }
  const std::string missing = test::message_of([&] { read_ply(dir / "absent.ply"); });
  EXPECT_TRUE(test::contains(missing, "absent.ply")) << missing;
  // Truncated binary body.
  write_ply(dir / "cut.ply", small_mesh());
  const auto size = std::filesystem::file_size(dir / "cut.ply");
  std::filesystem::resize_file(dir / "cut.ply", size - 5);
  EXPECT_TRUE(test::contains(test::message_of([&] { read_ply(dir / "cut.ply"); }), "truncated"));
}

TEST(Off, ReadsHeaderVariantsCommentsAndPolygons) {
  TempDir dir;
  write_bytes(dir / "a.off",
              "# leading comment\n\nOFF\n4 2 0\n0 0 0\n1 0 0 # trailing comment\n1 1 0\n0 1 0\n"
              "4 0 1 2 3\n3 0 2 3 255 0 0\n");
  const TriangleMesh a = read_off(dir / "a.off");
  ASSERT_EQ(a.vertex_count(), 4);
  ASSERT_EQ(a.triangle_count(), 3);
  EXPECT_EQ(a.triangles[1], (std::array<int32_t, 3>{0, 2, 3}));
  write_bytes(dir / "c.off", "COFF 2 0 0\n0 0 0 255 128 0 255\n1 1 1 0.5 1.0 0.0 1.0\n");
  const TriangleMesh c = read_off(dir / "c.off");
  ASSERT_EQ(c.colors.size(), 2u);
  EXPECT_EQ(c.colors[0], (Rgb8{255, 128, 0}));
  EXPECT_EQ(c.colors[1], (Rgb8{128, 255, 0}));
  write_bytes(dir / "bad.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 5\n");
  const std::string e = test::message_of([&] { read_off(dir / "bad.off"); });
  EXPECT_TRUE(test::contains(e, "bad.off:6")) << e;
  write_bytes(dir / "few.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n");
  EXPECT_TRUE(test::contains(test::message_of([&] { read_off(dir / "few.off"); }), "few.off"));
  // A corner count beyond the line is an error before anything is allocated for it (a fuzzer
  // found 555555555 taking seconds and gigabytes).
  write_bytes(dir / "corners.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n555555555 0 1 2\n");
  EXPECT_TRUE(test::contains(test::message_of([&] { read_off(dir / "corners.off"); }),
                             "declares 555555555 corners"));
  write_bytes(dir / "ply.off", "ply\n");
  EXPECT_TRUE(test::contains(test::message_of([&] { read_off(dir / "ply.off"); }), "OFF header"));
}

TEST(Ply, ReadsTheReplicaGroundTruthMesh) {
  HIVOX_REQUIRE_DATASET(dir, "replica_office0");
  const TriangleMesh m = read_ply(dir / "office0_mesh_decimated50k.ply");
  EXPECT_EQ(m.vertex_count(), 25149);
  EXPECT_EQ(m.triangle_count(), 50000);
  EXPECT_EQ(m.colors.size(), 25149u);  // red green blue (alpha ignored)
  EXPECT_TRUE(m.normals_w.empty());
  m.validate();
  // An office a few metres across.
  Vec3f lo{1e9f, 1e9f, 1e9f}, hi{-1e9f, -1e9f, -1e9f};
  for (const Vec3f& p : m.positions_w)
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], p[k]), hi[k] = std::max(hi[k], p[k]);
  for (int k = 0; k < 3; ++k) {
    EXPECT_GT(hi[k] - lo[k], 1.0f);
    EXPECT_LT(hi[k] - lo[k], 20.0f);
  }
}

TEST(Off, ReadsTheSharedGroundTruthShapes) {
  HIVOX_REQUIRE_DATASET(dir, "meshes");
  const TriangleMesh bunny = read_off(dir / "bunny00.off");
  EXPECT_EQ(bunny.vertex_count(), 37706);  // header: 37706 75408 0
  EXPECT_EQ(bunny.triangle_count(), 75408);
  bunny.validate();
  const TriangleMesh sphere = read_off(dir / "sphere966.off");  // comments before "OFF"
  EXPECT_EQ(sphere.vertex_count(), 926);
  EXPECT_EQ(sphere.triangle_count(), 1848);
}

}  // namespace
}  // namespace hivox

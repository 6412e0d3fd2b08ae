// OBJ meshes: what write_obj writes reads back the same; the forms of faces and indices other
// tools write; errors that name the file and line.

#include "hivox/io/obj.h"

#include <gtest/gtest.h>

#include "hivox/core/error.h"
#include "hivox/io/mesh_file.h"
#include "test_util.h"

namespace hivox {
namespace {

TEST(Obj, WhatIsWrittenReadsBack) {
  test::TempDir dir;
  TriangleMesh m;
  m.positions_w = {{0.125f, -2.5f, 3.0f}, {1, 0, 0}, {0, 1, 0.333333f}, {1, 1, 1}};
  m.colors = {{255, 0, 10}, {1, 2, 3}, {100, 200, 250}, {0, 0, 0}};
  m.normals_w = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {0, 0, 1}};
  m.triangles = {{0, 1, 2}, {1, 3, 2}};
  write_obj(dir / "m.obj", m);
  const TriangleMesh r = read_mesh(dir / "m.obj");
  ASSERT_EQ(r.vertex_count(), 4);
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(r.positions_w[i].x, m.positions_w[i].x);
    EXPECT_EQ(r.positions_w[i].y, m.positions_w[i].y);
    EXPECT_EQ(r.positions_w[i].z, m.positions_w[i].z);
    EXPECT_EQ(r.colors[i], m.colors[i]);
  }
  EXPECT_EQ(r.triangles, m.triangles);
}

TEST(Obj, ReadsPolygonsNegativeIndicesAndCornerForms) {
  test::TempDir dir;
  test::write_text(dir / "q.obj",
                   "# a quad and a triangle\n"
                   "mtllib x.mtl\no thing\n"
                   "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                   "vt 0 0\nvn 0 0 1\ns off\n"
                   "f 1/1/1 2/1/1 3/1/1 4/1/1\n"
                   "f -1 -3 -2\n"
                   "f 1//1 2//1 4//1\n");
  const TriangleMesh m = read_obj(dir / "q.obj");
  EXPECT_EQ(m.vertex_count(), 4);
  EXPECT_TRUE(m.colors.empty());
  const std::vector<std::array<int32_t, 3>> expected = {{0, 1, 2}, {0, 2, 3}, {3, 1, 2}, {0, 1, 3}};
  EXPECT_EQ(m.triangles, expected);
}

TEST(Obj, ErrorsNameTheFileAndLine) {
  test::TempDir dir;
  const auto expect_error = [&](const std::string& text, const std::string& words) {
    test::write_text(dir / "bad.obj", text);
    try {
      read_obj(dir / "bad.obj");
      ADD_FAILURE() << text;
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::InvalidData) << e.what();
      EXPECT_TRUE(test::contains(e.what(), (dir / "bad.obj").string())) << e.what();
      EXPECT_TRUE(test::contains(e.what(), words)) << e.what();
    }
  };
  expect_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", ":4: face vertex '4'");
  expect_error("v 0 0 0\nv 1 0 0\nf 1 2\n", "at least 3 corners");
  expect_error("v 0 0 0\nf 0 1 1\n", "face vertex '0'");
  expect_error("v 0 zero 0\n", ":1:");
  expect_error("f 1 2 3\n", "face vertex '1'");
  expect_error("# nothing\n", "no vertices");
  EXPECT_THROW(read_obj(dir / "missing.obj"), Error);
}

}  // namespace
}  // namespace hivox

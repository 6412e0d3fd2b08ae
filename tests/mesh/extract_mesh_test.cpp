#include "hivox/mesh/extract_mesh.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <set>
#include <tuple>

#include "test_util.h"

#include "analytic_scene.h"
#include "hivox/core/error.h"
#include "hivox/core/threads.h"
#include "map/map_access.h"
#include "map/split_util.h"
#include "mesh/mesh_test_util.h"
#include "mesh/mesh_topology.h"

namespace hivox {
namespace {

using test::to_eigen;

std::string error_of(const MeshParams& p) {
  try {
    p.validate();
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::InvalidArgument);
    return e.what();
  }
  return "";
}

/// Number of vertices whose position equals another vertex's. (Distinct vertices can still be
/// very close: a TSDF value of a few int16 units puts the crossings of its edges next to the
/// voxel, so only exact equality identifies a duplicate.)
int64_t duplicate_positions(const TriangleMesh& m) {
  std::vector<std::tuple<float, float, float>> p;
  for (const Vec3f& v : m.positions_w) p.emplace_back(v.x, v.y, v.z);
  std::sort(p.begin(), p.end());
  int64_t n = 0;
  for (std::size_t i = 1; i < p.size(); ++i) n += p[i] == p[i - 1];
  return n;
}

/// Triangles whose vertices fall in different blocks (so they are stitched across a border).
int64_t triangles_across_blocks(const TriangleMesh& m, double block_m) {
  int64_t n = 0;
  for (const auto& t : m.triangles) {
    std::set<std::tuple<int, int, int>> blocks;
    for (const int32_t i : t) {
      const Vec3f& p = m.positions_w[static_cast<std::size_t>(i)];
      blocks.emplace(static_cast<int>(std::floor(p.x / block_m)),
                     static_cast<int>(std::floor(p.y / block_m)),
                     static_cast<int>(std::floor(p.z / block_m)));
    }
    n += blocks.size() > 1;
  }
  return n;
}

void expect_same_mesh(const TriangleMesh& a, const TriangleMesh& b) {
  ASSERT_EQ(a.vertex_count(), b.vertex_count());
  ASSERT_EQ(a.triangle_count(), b.triangle_count());
  for (std::size_t i = 0; i < a.positions_w.size(); ++i) {
    ASSERT_EQ(a.positions_w[i].x, b.positions_w[i].x) << i;
    ASSERT_EQ(a.positions_w[i].y, b.positions_w[i].y) << i;
    ASSERT_EQ(a.positions_w[i].z, b.positions_w[i].z) << i;
    ASSERT_EQ(a.normals_w[i].x, b.normals_w[i].x) << i;
    ASSERT_EQ(a.levels[i], b.levels[i]) << i;
  }
  ASSERT_EQ(a.colors.size(), b.colors.size());
  for (std::size_t i = 0; i < a.colors.size(); ++i) ASSERT_EQ(a.colors[i], b.colors[i]) << i;
  for (std::size_t i = 0; i < a.triangles.size(); ++i) ASSERT_EQ(a.triangles[i], b.triangles[i]);
}

// ---- maps written from an exact SDF ---------------------------------------------------------

TEST(ExtractMesh, EmptyMapGivesEmptyMesh) {
  VoxelBlockMap map(test::mesh_map_params(0.01f));
  const TriangleMesh m = extract_mesh(map);
  EXPECT_EQ(m.vertex_count(), 0);
  EXPECT_EQ(m.triangle_count(), 0);
}

TEST(ExtractMesh, PlaneGivesTheExactGridOfVertices) {
  // A horizontal plane through blocks x in [-2, 1], y in [-1, 1], z = 0 (negative coordinates
  // included). Every z edge of the 32 x 24 columns crosses it once; cells need their +x/+y
  // neighbour voxels, so the last column/row of cells is missing and the rest are 2 triangles.
  const float voxel = 0.01f;
  const double plane_z = 0.0437, mu = 0.04;
  VoxelBlockMap map(test::mesh_map_params(voxel));
  test::write_sdf_blocks(map, 0, {-2, -1, 0}, {1, 1, 0}, mu,
                         [&](const Eigen::Vector3d& p) { return p.z() - plane_z; });
  const TriangleMesh m = extract_mesh(map);
  ASSERT_EQ(m.vertex_count(), 32 * 24);
  EXPECT_EQ(m.triangle_count(), 2 * 31 * 23);
  std::set<std::pair<int, int>> columns;
  for (std::size_t i = 0; i < m.positions_w.size(); ++i) {
    const Vec3f& p = m.positions_w[i];
    EXPECT_NEAR(p.z, plane_z, 1e-4);
    columns.emplace(static_cast<int>(std::lround(p.x / voxel)),
                    static_cast<int>(std::lround(p.y / voxel)));
    EXPECT_NEAR(m.normals_w[i].z, 1.0f, 1e-5);
    EXPECT_EQ(m.levels[i], 0);
  }
  EXPECT_EQ(columns.size(), 32u * 24u);
  EXPECT_EQ(columns.begin()->first, -16);
  EXPECT_EQ(columns.begin()->second, -8);
  for (const auto& t : m.triangles) {
    const Vec3f a = m.positions_w[t[0]], b = m.positions_w[t[1]], c = m.positions_w[t[2]];
    const Vec3f n = cross(b - a, c - a);
    EXPECT_GT(n.z, 0.0f) << "triangle faces away from free space";
  }
  // No colour was fused: map colour exists, every vertex is mid-grey.
  ASSERT_EQ(m.colors.size(), m.positions_w.size());
  EXPECT_EQ(m.colors.front(), (Rgb8{128, 128, 128}));
  const test::MeshTopology topo = test::mesh_topology(m.vertex_count(), m.triangles);
  EXPECT_EQ(topo.nonmanifold_edges + topo.misoriented_edges + topo.nonmanifold_vertices, 0);
  EXPECT_EQ(topo.unused_vertices, 0);
  EXPECT_EQ(topo.euler(), 1);  // a disc
}

/// A sphere written straight from its SDF into 1 cm voxels, off the grid and across many blocks
/// (and the origin, so negative block coordinates too).
/// Returns the sphere's centre and SDF.
Eigen::Vector3d write_exact_sphere(VoxelBlockMap& map, test::Sdf* sdf_out = nullptr) {
  const double mu = 0.04, r = 0.173;
  const Eigen::Vector3d c(0.0123, -0.0311, 0.0457);
  const test::Sdf sdf = [c, r](const Eigen::Vector3d& p) { return (p - c).norm() - r; };
  test::write_sdf_band(map, 0, c.array() - 0.3, c.array() + 0.3, mu, mu, sdf);
  if (sdf_out) *sdf_out = sdf;
  return c;
}

TEST(ExtractMesh, ExactSphereIsAClosedManifoldWithSharedVertices) {
  const float voxel = 0.01f;
  VoxelBlockMap map(test::mesh_map_params(voxel));
  test::Sdf sdf;
  const Eigen::Vector3d c = write_exact_sphere(map, &sdf);
  const TriangleMesh m = extract_mesh(map);
  ASSERT_GT(m.triangle_count(), 5000);
  const test::MeshTopology topo = test::mesh_topology(m.vertex_count(), m.triangles);
  EXPECT_TRUE(topo.closed_manifold())
      << "boundary " << topo.boundary_edges << ", non-manifold " << topo.nonmanifold_edges
      << ", misoriented " << topo.misoriented_edges << ", bad vertices "
      << topo.nonmanifold_vertices;
  EXPECT_EQ(topo.euler(), 2);
  EXPECT_EQ(topo.components, 1);
  EXPECT_EQ(topo.unused_vertices, 0);
  EXPECT_EQ(duplicate_positions(m), 0);
  EXPECT_GT(triangles_across_blocks(m, 8 * voxel), 500);
  double max_err = 0, min_dot = 1;
  for (std::size_t i = 0; i < m.positions_w.size(); ++i) {
    const Eigen::Vector3d p = to_eigen(m.positions_w[i]);
    max_err = std::max(max_err, std::abs(sdf(p)));
    min_dot = std::min(min_dot, to_eigen(m.normals_w[i]).dot((p - c).normalized()));
  }
  // Linear interpolation of an exact SDF along an edge: error ~ voxel^2 / (2 r) plus int16
  // rounding.
  EXPECT_LT(max_err, 0.02 * voxel);
  EXPECT_GT(min_dot, 0.99);
}

TEST(ExtractMesh, UnobservedAndLowWeightVoxelsMakeNoSurface) {
  const float voxel = 0.01f;
  const double plane_z = 0.0437, mu = 0.04;
  auto plane = [&](const Eigen::Vector3d& p) { return p.z() - plane_z; };
  VoxelBlockMap map(test::mesh_map_params(voxel));
  test::write_sdf_blocks(map, 0, {0, 0, 0}, {1, 1, 0}, mu, plane);
  const TriangleMesh full = extract_mesh(map);
  // Unobserve voxel (5, 6, 4), just below the plane: the 8 cells around it go, and with them
  // every vertex on an edge of that voxel.
  const Vec3i hole{5, 6, 4};
  const int32_t ptr = map.find(0, {0, 0, 0})->ptr;
  MapAccess::tsdf(map, ptr)[local_voxel_index(hole)].weight = 0;
  MapAccess::refresh_surface(map, ptr);
  const TriangleMesh holed = extract_mesh(map);
  EXPECT_EQ(holed.vertex_count(), full.vertex_count() - 1);
  EXPECT_EQ(holed.triangle_count(), full.triangle_count() - 8);
  for (const Vec3f& p : holed.positions_w)
    EXPECT_FALSE(std::lround(p.x / voxel) == hole.x && std::lround(p.y / voxel) == hole.y)
        << "vertex on an edge of the unobserved voxel";
  const test::MeshTopology topo = test::mesh_topology(holed.vertex_count(), holed.triangles);
  EXPECT_EQ(topo.unused_vertices, 0);
  // Raising min_weight above every weight removes everything.
  MeshParams p;
  p.min_weight = 2;
  EXPECT_EQ(extract_mesh(map, p).vertex_count(), 0);
  // Half the plane seen twice: only that half survives min_weight 2.
  test::write_sdf_blocks(map, 0, {2, 0, 0}, {3, 1, 0}, mu, plane, 2);
  const TriangleMesh twice = extract_mesh(map, p);
  ASSERT_GT(twice.vertex_count(), 0);
  for (const Vec3f& v : twice.positions_w) EXPECT_GE(v.x, 16 * voxel - 1e-6);
}

/// split_down, then the exact `sdf` written into every level-0 block.
void split_to_finest_exact(VoxelBlockMap& map, int level, double mu_m, const test::Sdf& sdf,
                           const std::function<bool(const BlockRef&)>& pick) {
  test::split_down(map, level, pick, 0.0f);
  for (const BlockRef& b : map.allocated_blocks())
    if (b.level == 0) test::write_sdf_voxels(map, b, mu_m, sdf);
}

TEST(ExtractMesh, EveryLevelIsMeshedAtItsOwnVoxelSizeUpToTheBoundary) {
  // Two levels side by side: level 0 (1 cm) for x < 0, level 1 (2 cm) for x >= 0. Each part
  // is an exact grid of vertices at its own spacing, and the fine cells reach the boundary
  // plane x = 0 by sampling the coarse level there: the surface has no gap, the fine grid
  // ends on the coarse grid's first column.
  const float voxel = 0.01f;
  const double plane_z = 0.0437, mu = 0.08;
  auto plane = [&](const Eigen::Vector3d& p) { return p.z() - plane_z; };
  VoxelBlockMap map(test::mesh_map_params(voxel, 2));
  test::write_sdf_blocks(map, 1, {-1, 0, 0}, {0, 0, 0}, mu, plane);  // x in [-0.16, 0.16)
  split_to_finest_exact(map, 1, mu, plane, [](const BlockRef& b) { return b.pos.x < 0; });
  const TriangleMesh m = extract_mesh(map);
  int64_t per_level[2] = {0, 0}, on_boundary[2] = {0, 0};
  for (std::size_t i = 0; i < m.positions_w.size(); ++i) {
    const Vec3f& p = m.positions_w[i];
    const int l = m.levels[i];
    ASSERT_LT(l, 2);
    ++per_level[l];
    on_boundary[l] += p.x == 0.0f;
    EXPECT_TRUE(l == 1 ? p.x >= 0.0f : p.x <= 0.0f) << p.x;
    const float s = voxel * static_cast<float>(1 << l);
    EXPECT_NEAR(p.x / s, std::round(p.x / s), 1e-3);
    EXPECT_NEAR(p.y / s, std::round(p.y / s), 1e-3);
    EXPECT_NEAR(p.z, plane_z, 1e-4);
  }
  // Fine: 16 columns of own voxels by 16 rows, plus the boundary column x = 0, which takes the
  // coarse level's values: its rows end where the coarse grid's data does (y = 14 cm; at 15 cm
  // the coarse edge has no far end), so the last fine cell row stops one cell short there.
  // Coarse: 8 x 8, cells up to the last column and row.
  EXPECT_EQ(per_level[0], 16 * 16 + 15);
  EXPECT_EQ(on_boundary[0], 15);
  EXPECT_EQ(per_level[1], 8 * 8);
  EXPECT_EQ(on_boundary[1], 8);
  EXPECT_EQ(m.triangle_count(), 2 * 16 * 15 - 2 + 2 * 7 * 7);
}

/// The seam where levels meet: for points along every boundary edge (an edge of one triangle)
/// of one level, the distance to the nearest boundary edge of another level; the largest.
/// Where the levels' surfaces meet, it is ~0; a crack between them shows as its width.
double widest_seam_gap(const TriangleMesh& m, const std::function<bool(const Vec3f&)>& on_seam,
                       int64_t* seam_edges_per_level) {
  std::map<std::pair<int32_t, int32_t>, int> uses;
  for (const auto& t : m.triangles)
    for (int k = 0; k < 3; ++k) ++uses[std::minmax(t[k], t[(k + 1) % 3])];
  std::vector<std::pair<int32_t, int32_t>> edges;
  for (const auto& [e, n] : uses)
    if (n == 1 && on_seam(m.positions_w[e.first]) && on_seam(m.positions_w[e.second]))
      edges.push_back(e);
  for (const auto& e : edges) ++seam_edges_per_level[m.levels[e.first]];
  auto distance_to_segment = [](const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                const Eigen::Vector3d& b) {
    const double t = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
    return (a + t * (b - a) - p).norm();
  };
  double widest = 0;
  for (const auto& e : edges) {
    const Eigen::Vector3d a = to_eigen(m.positions_w[e.first]),
                          b = to_eigen(m.positions_w[e.second]);
    for (int k = 0; k <= 4; ++k) {
      const Eigen::Vector3d p = a + (b - a) * (k / 4.0);
      double nearest = 1e9;
      for (const auto& o : edges)
        if (m.levels[o.first] != m.levels[e.first])
          nearest = std::min(nearest, distance_to_segment(p, to_eigen(m.positions_w[o.first]),
                                                          to_eigen(m.positions_w[o.second])));
      widest = std::max(widest, nearest);
    }
  }
  return widest;
}

TEST(ExtractMesh, SphereAcrossLevelsHasNoCrackWhereTheyMeet) {
  // An exact sphere stored at the coarsest level for x < 0 and the finest for x >= 0, with one
  // and two levels between them. The only boundary edges of the (closed) surface are on the
  // boundary plane, where both sides cut it along the same curve.
  for (const int levels : {2, 3}) {
    SCOPED_TRACE(levels);
    const float voxel = 0.005f;
    const double mu = 4 * voxel * (1 << (levels - 1)), r = 0.173;
    const Eigen::Vector3d centre(0.0123, 0.0311, -0.0207);
    auto sphere = [&](const Eigen::Vector3d& p) { return (p - centre).norm() - r; };
    VoxelBlockMap map(test::mesh_map_params(voxel, levels));
    test::write_sdf_band(map, levels - 1, centre - Eigen::Vector3d::Constant(0.3),
                         centre + Eigen::Vector3d::Constant(0.3), mu, mu, sphere);
    split_to_finest_exact(map, levels - 1, mu, sphere,
                          [](const BlockRef& b) { return b.pos.x >= 0; });
    const TriangleMesh m = extract_mesh(map);
    int64_t seam_edges[4] = {0, 0, 0, 0};
    const double gap = widest_seam_gap(
        m, [](const Vec3f& p) { return std::abs(p.x) < 1e-6f; }, seam_edges);
    EXPECT_GT(seam_edges[0], 100);
    EXPECT_GT(seam_edges[levels - 1], 100 >> (levels - 1));
    EXPECT_LT(gap, 0.05 * voxel);
    const test::MeshTopology topo = test::mesh_topology(m.vertex_count(), m.triangles);
    EXPECT_EQ(topo.boundary_edges, seam_edges[0] + seam_edges[levels - 1]);
    EXPECT_EQ(topo.nonmanifold_edges + topo.misoriented_edges + topo.degenerate_triangles, 0);
    EXPECT_EQ(topo.unused_vertices, 0);
    double max_err = 0;
    for (const Vec3f& p : m.positions_w) max_err = std::max(max_err, std::abs(sphere(to_eigen(p))));
    EXPECT_LT(max_err, 0.5 * voxel * (1 << (levels - 1)));
  }
}

TEST(ExtractMesh, FusedSceneAcrossLevelsHasNoCrackWhereTheyMeet) {
  // The sphere on its floor fused from depth images, with the region x >= 0 split to the
  // finest level (4 mm) and fused again, x < 0 kept at the coarsest (16 mm). Where both levels
  // hold the sphere, their surfaces meet on the plane x = 0 within a fraction of a fine voxel
  // (cutting every cell off at the boundary would leave a gap of a cell; sampling the other
  // level without holding the fine side to the coarse lattice there, up to 5 voxels where the
  // two sides' contours take different shapes). The floor is left out: at its far
  // edge the fine side's data reaches further than the coarse side's, a border, not a crack.
  test::SphereOnPlane scene;
  const float voxel = 0.004f, mu = 0.048f;
  VoxelBlockMap map(test::mesh_map_params(voxel, 3, true, mu));
  test::fuse_views(map, scene, 16, {0.5, 0.2});
  test::split_down(
      map, 2, [](const BlockRef& b) { return b.pos.x >= 0; }, 0.0f);
  test::fuse_views(map, scene, 16, {0.5, 0.2});
  const TriangleMesh m = extract_mesh(map);
  int64_t seam_edges[4] = {0, 0, 0, 0};
  const double gap = widest_seam_gap(
      m, [](const Vec3f& p) { return std::abs(p.x) < 1e-6f && p.z > 0.05f; }, seam_edges);
  EXPECT_GT(seam_edges[0], 100);
  EXPECT_GT(seam_edges[2], 25);
  EXPECT_LT(gap, 0.3 * voxel);
}

TEST(ExtractMesh, ColourNormalsAndLevelsFollowTheParams) {
  const float voxel = 0.01f;
  VoxelBlockMap map(test::mesh_map_params(voxel, 1, /*color=*/false));
  test::write_sdf_blocks(map, 0, {0, 0, 0}, {0, 0, 0}, 0.04,
                         [](const Eigen::Vector3d& p) { return p.z() - 0.033; });
  MeshParams p;
  TriangleMesh m = extract_mesh(map, p);
  EXPECT_TRUE(m.colors.empty()) << "the map stores no colour";
  EXPECT_EQ(m.normals_w.size(), m.positions_w.size());
  EXPECT_EQ(m.levels.size(), m.positions_w.size());
  p.compute_normals = false;
  m = extract_mesh(map, p);
  EXPECT_TRUE(m.normals_w.empty());
  EXPECT_GT(m.vertex_count(), 0);
  m.validate();
}

TEST(ExtractMesh, BadParamsAreRejectedNamingTheField) {
  MeshParams p;
  EXPECT_EQ(error_of(p), "");
  for (const float bad : {0.0f, 0.5f, -1.0f, NAN, INFINITY, 70000.0f}) {
    p.min_weight = bad;
    EXPECT_TRUE(test::contains(error_of(p), "min_weight")) << bad;
    VoxelBlockMap map(test::mesh_map_params(0.01f));
    EXPECT_THROW(extract_mesh(map, p), Error);
  }
  EXPECT_TRUE(test::contains(MeshParams{}.to_string(), "min weight 1"));
}

// ---- maps fused from rendered depth ---------------------------------------------------------

class FusedSphereOnPlane : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const Rgb8 colour{200, 100, 50};
    map_ = test::fuse_scene(scene(), kVoxel, kMu, 16, {0.5}, &colour).release();
    mesh_ = new TriangleMesh(extract_mesh(*map_));
  }
  static void TearDownTestSuite() {
    delete mesh_;
    delete map_;
  }
  static test::SphereOnPlane scene() { return {}; }
  static constexpr float kVoxel = 0.008f;
  static constexpr float kMu = 4 * kVoxel;
  static VoxelBlockMap* map_;
  static TriangleMesh* mesh_;
};
VoxelBlockMap* FusedSphereOnPlane::map_ = nullptr;
TriangleMesh* FusedSphereOnPlane::mesh_ = nullptr;

TEST_F(FusedSphereOnPlane, VerticesLieOnTheTrueSurface) {
  const TriangleMesh& m = *mesh_;
  ASSERT_GT(m.vertex_count(), 20000);
  const test::SphereOnPlane s = scene();
  double sum = 0, max_err = 0;
  for (const Vec3f& p : m.positions_w) {
    const double err = std::abs(s.sdf(to_eigen(p)));
    sum += err;
    max_err = std::max(max_err, err);
  }
  EXPECT_LT(sum / static_cast<double>(m.vertex_count()), 0.1 * kVoxel);
  EXPECT_LT(max_err, 0.5 * kVoxel);
}

TEST_F(FusedSphereOnPlane, CoversTheObservedSurface) {
  // Points on the sphere's upper part (seen by every camera of the orbit at some angle) and
  // on the floor ring around it: each has a mesh vertex within one voxel.
  const test::SphereOnPlane s = scene();
  const TriangleMesh& m = *mesh_;
  std::vector<Eigen::Vector3d> samples;
  for (int i = 0; i < 400; ++i) {
    const double a = 2 * M_PI * i / 400.0, e = (i * 37 % 100) / 100.0 * 1.4;  // up to 80 deg
    samples.push_back(s.centre + s.radius * Eigen::Vector3d(std::cos(a) * std::cos(e),
                                                            std::sin(a) * std::cos(e),
                                                            std::sin(e)));
    const double rr = 0.3 + 0.15 * (i * 53 % 100) / 100.0;
    samples.emplace_back(s.centre.x() + rr * std::cos(a), s.centre.y() + rr * std::sin(a),
                         s.floor_z);
  }
  // Bucket vertices by voxel for a quick nearest search.
  std::set<std::tuple<int, int, int>> occupied;
  std::vector<Eigen::Vector3d> verts;
  for (const Vec3f& p : m.positions_w) verts.push_back(to_eigen(p));
  std::sort(verts.begin(), verts.end(),
            [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) { return a.x() < b.x(); });
  int uncovered = 0;
  for (const Eigen::Vector3d& q : samples) {
    const auto lo = std::lower_bound(verts.begin(), verts.end(), q.x() - kVoxel,
                                     [](const Eigen::Vector3d& v, double x) { return v.x() < x; });
    bool found = false;
    for (auto it = lo; it != verts.end() && it->x() <= q.x() + kVoxel && !found; ++it)
      found = (*it - q).norm() <= kVoxel;
    uncovered += !found;
  }
  EXPECT_EQ(uncovered, 0) << "of " << samples.size() << " samples";
}

TEST_F(FusedSphereOnPlane, VerticesAreSharedAcrossBlockBordersAndAllUsed) {
  const TriangleMesh& m = *mesh_;
  EXPECT_EQ(duplicate_positions(m), 0);
  EXPECT_GT(triangles_across_blocks(m, 8 * kVoxel), 2000);
  const test::MeshTopology topo = test::mesh_topology(m.vertex_count(), m.triangles);
  EXPECT_EQ(topo.unused_vertices, 0);
  EXPECT_EQ(topo.degenerate_triangles, 0);
  EXPECT_EQ(topo.nonmanifold_edges, 0);
  EXPECT_EQ(topo.misoriented_edges, 0);
}

TEST_F(FusedSphereOnPlane, NormalsAreUnitAndPointToFreeSpace) {
  const TriangleMesh& m = *mesh_;
  const test::SphereOnPlane s = scene();
  const test::Sdf sdf = [&](const Eigen::Vector3d& p) { return s.sdf(p); };
  ASSERT_EQ(m.normals_w.size(), m.positions_w.size());
  double sum = 0;
  for (std::size_t i = 0; i < m.positions_w.size(); ++i) {
    const Eigen::Vector3d n = to_eigen(m.normals_w[i]);
    ASSERT_NEAR(n.norm(), 1.0, 1e-4);
    sum += n.dot(test::sdf_gradient(sdf, to_eigen(m.positions_w[i])).normalized());
  }
  EXPECT_GT(sum / static_cast<double>(m.vertex_count()), 0.95);
  // Triangle winding agrees with the vertex normals.
  int64_t agree = 0;
  for (const auto& t : m.triangles) {
    const Vec3f a = m.positions_w[t[0]], b = m.positions_w[t[1]], c = m.positions_w[t[2]];
    agree +=
        dot(cross(b - a, c - a), m.normals_w[t[0]] + m.normals_w[t[1]] + m.normals_w[t[2]]) > 0.0f;
  }
  EXPECT_GT(static_cast<double>(agree), 0.99 * static_cast<double>(m.triangle_count()));
}

TEST_F(FusedSphereOnPlane, ColoursComeFromTheVoxels) {
  const TriangleMesh& m = *mesh_;
  ASSERT_EQ(m.colors.size(), m.positions_w.size());
  int64_t fused = 0;
  for (const Rgb8& c : m.colors) fused += c == Rgb8{200, 100, 50};
  EXPECT_GT(static_cast<double>(fused), 0.99 * static_cast<double>(m.vertex_count()));
  MeshParams p;
  p.with_color = false;
  EXPECT_TRUE(extract_mesh(*map_, p).colors.empty());
}

TEST_F(FusedSphereOnPlane, OutputDoesNotDependOnTheThreadCount) {
  for (const int threads : {1, 2, 3}) {
    set_thread_count(threads);
    const TriangleMesh m = extract_mesh(*map_);
    set_thread_count(0);
    SCOPED_TRACE(threads);
    expect_same_mesh(m, *mesh_);
  }
}

TEST(ExtractMesh, OutputDoesNotDependOnPoolOrder) {
  // The same scene fused with 1 and 3 threads: blocks land in different pool slots, the voxel
  // values are the same, and so must be the mesh.
  const test::SphereOnPlane scene;
  set_thread_count(1);
  const auto a = test::fuse_scene(scene, 0.01f, 0.04f, 6, {0.5});
  set_thread_count(3);
  const auto b = test::fuse_scene(scene, 0.01f, 0.04f, 6, {0.5});
  const TriangleMesh ma = extract_mesh(*a);
  const TriangleMesh mb = extract_mesh(*b);
  set_thread_count(0);
  ASSERT_GT(ma.triangle_count(), 1000);
  expect_same_mesh(ma, mb);
}

TEST(ExtractMesh, FloatingSphereSeenFromAllSidesIsWatertight) {
  test::SphereOnPlane scene;
  scene.with_floor = false;
  const float voxel = 0.008f;
  const auto map = test::fuse_scene(scene, voxel, 4 * voxel, 12, {0.5, -0.5});
  const TriangleMesh m = extract_mesh(*map);
  ASSERT_GT(m.triangle_count(), 10000);
  const test::MeshTopology topo = test::mesh_topology(m.vertex_count(), m.triangles);
  EXPECT_EQ(topo.boundary_edges, 0);
  EXPECT_EQ(topo.nonmanifold_edges, 0);
  EXPECT_EQ(topo.misoriented_edges, 0);
  EXPECT_EQ(topo.nonmanifold_vertices, 0);
  EXPECT_EQ(topo.degenerate_triangles, 0);
  EXPECT_EQ(topo.unused_vertices, 0);
  EXPECT_EQ(topo.components, 1);
  EXPECT_EQ(topo.euler(), 2);
  double max_err = 0;
  for (const Vec3f& p : m.positions_w)
    max_err = std::max(max_err, std::abs(scene.sdf(to_eigen(p))));
  EXPECT_LT(max_err, 0.5 * voxel);
}

/// The triangles of a mesh as sets of corner positions, independent of vertex numbering.
std::multiset<std::array<float, 9>> triangle_set(const TriangleMesh& m) {
  std::multiset<std::array<float, 9>> out;
  for (const auto& t : m.triangles) {
    std::array<float, 9> k{};
    for (int c = 0; c < 3; ++c)
      for (int a = 0; a < 3; ++a) k[3 * c + a] = m.positions_w[t[c]][a];
    out.insert(k);
  }
  return out;
}

// Meshing inside bounds (blocks outside skipped) gives exactly the triangles of the whole mesh
// whose corners lie inside.
TEST(MeshBounds, BoundsGiveTheWholeMeshCropped) {
  VoxelBlockMap map(test::mesh_map_params(0.01f));
  write_exact_sphere(map);
  const TriangleMesh whole = extract_mesh(map);
  MeshParams p;
  p.bounds = Box3f{{-0.05f, -0.3f, -0.02f}, {0.3f, 0.07f, 0.4f}};
  const TriangleMesh inside = extract_mesh(map, p);
  const TriangleMesh cropped = crop_mesh(whole, *p.bounds);
  EXPECT_GT(inside.triangle_count(), 500);
  EXPECT_LT(inside.triangle_count(), whole.triangle_count() / 2);
  EXPECT_TRUE(triangle_set(inside) == triangle_set(cropped));
  for (const Vec3f& v : inside.positions_w) EXPECT_TRUE(p.bounds->contains(v));
  const test::MeshTopology topo = test::mesh_topology(inside.vertex_count(), inside.triangles);
  EXPECT_EQ(topo.unused_vertices, 0);
  EXPECT_EQ(duplicate_positions(inside), 0);
  p.bounds = Box3f{{1.0f, 1.0f, 1.0f}, {2.0f, 2.0f, 2.0f}};
  EXPECT_EQ(extract_mesh(map, p).triangle_count(), 0);
  p.bounds = Box3f{{1.0f, 1.0f, 1.0f}, {0.0f, 2.0f, 2.0f}};
  EXPECT_TRUE(test::contains(test::error_of([&] { extract_mesh(map, p); }).what(), "min <= max"));
}

// A small sphere beside a big one is a piece of its own and goes; the big one stays whole.
TEST(MeshPieces, SmallPiecesAreRemovedBigOnesKept) {
  const float voxel = 0.01f;
  const double mu = 0.04;
  const Eigen::Vector3d big(0.0, 0.0, 0.0), small(0.5, 0.0, 0.0);
  const test::Sdf sdf = [&](const Eigen::Vector3d& p) {
    return std::min((p - big).norm() - 0.2, (p - small).norm() - 0.05);
  };
  VoxelBlockMap map(test::mesh_map_params(voxel));
  test::write_sdf_band(map, 0, {-0.3, -0.3, -0.3}, {0.6, 0.3, 0.3}, mu, mu, sdf);
  const TriangleMesh all = extract_mesh(map);
  MeshParams p;
  p.min_piece_triangles = 2000;
  int64_t removed = -1;
  const TriangleMesh kept = remove_small_pieces(all, p.min_piece_triangles, voxel, &removed);
  EXPECT_EQ(removed, 1);
  EXPECT_LT(kept.triangle_count(), all.triangle_count());
  for (const Vec3f& v : kept.positions_w) EXPECT_LT(v.x, 0.3f);
  const test::MeshTopology topo = test::mesh_topology(kept.vertex_count(), kept.triangles);
  EXPECT_EQ(topo.components, 1);
  EXPECT_TRUE(topo.closed_manifold());
  EXPECT_EQ(extract_mesh(map, p).triangle_count(), kept.triangle_count());
  EXPECT_EQ(remove_small_pieces(all, 1, voxel).triangle_count(), all.triangle_count());
}

// Across a change of level the two sides share no vertex, but they are one piece.
TEST(MeshPieces, APieceSpanningTwoLevelsIsOnePiece) {
  const float voxel = 0.01f;
  const double plane_z = 0.0437, mu = 0.08;
  auto plane = [&](const Eigen::Vector3d& p) { return p.z() - plane_z; };
  VoxelBlockMap map(test::mesh_map_params(voxel, 2));
  test::write_sdf_blocks(map, 1, {-1, 0, 0}, {0, 0, 0}, mu, plane);
  split_to_finest_exact(map, 1, mu, plane, [](const BlockRef& b) { return b.pos.x < 0; });
  const TriangleMesh m = extract_mesh(map);
  const test::MeshTopology topo = test::mesh_topology(m.vertex_count(), m.triangles);
  ASSERT_EQ(topo.components, 2) << "the levels' parts share no vertex";
  int64_t removed = -1;
  const TriangleMesh kept = remove_small_pieces(m, m.triangle_count() * 2 / 3, voxel, &removed);
  EXPECT_EQ(removed, 0);
  EXPECT_EQ(kept.triangle_count(), m.triangle_count());
}

}  // namespace
}  // namespace hivox

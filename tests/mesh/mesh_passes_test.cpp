// Meshing in passes (src/mesh/mesh_passes.h), the CUDA mesher's per-block and per-corner steps,
// run here one block at a time on the host: they must give extract_mesh's mesh exactly, across
// levels, with and without normals and colour.

#include "mesh/mesh_passes.h"

#include <gtest/gtest.h>

#include <memory>
#include <regex>
#include <string>
#include <vector>

#include "hivox/mesh/extract_mesh.h"
#include "map/split_util.h"
#include "mesh/mesh_test_util.h"

namespace hivox {
namespace {

struct PassesResult {
  TriangleMesh mesh;
  int64_t unresolved = 0;         ///< corners that found no vertex
  int64_t boundary_vertices = 0;  ///< made by several blocks each, merged
};

/// The passes as the CUDA mesher runs them, one block (one corner) after another.
PassesResult mesh_in_passes(const VoxelBlockMap& map, const MeshParams& params) {
  PassesResult r;
  const MapView view = map.view();
  // The blocks found by binary search, as a driver without the hash tables finds them.
  const detail::MeshBlocks plan = detail::plan_mesh_blocks(
      map.allocated_blocks(), map.block_high_water(), map.params(), params.bounds);
  const std::vector<BlockRef>& blocks = plan.blocks;
  const auto n = static_cast<int32_t>(blocks.size());

  kernels::MeshPassInput in = detail::mesh_pass_input(params, view.color != nullptr, plan);
  const auto cache = std::make_unique<kernels::BlockLookupCache>();
  const auto scratch = std::make_unique<kernels::MeshBlockScratch>();

  std::vector<kernels::BlockMeshCount> counts(blocks.size());
  for (int32_t i = 0; i < n; ++i)
    counts[static_cast<std::size_t>(i)] = kernels::count_block_mesh(view, *cache, in, i, *scratch);
  for (const kernels::BlockMeshCount& k : counts) r.boundary_vertices += k.vertices - k.owned;
  const detail::MeshLayout layout = detail::mesh_layout(counts.data(), n);
  in.counts = counts.data();
  in.vertex_offset = layout.vertex_offset.data();
  in.corner_offset = layout.corner_offset.data();

  const auto vertices = static_cast<std::size_t>(layout.vertices());
  TriangleMesh mesh;
  mesh.positions_w.resize(vertices);
  if (in.normals) mesh.normals_w.resize(vertices);
  if (in.color) mesh.colors.resize(vertices);
  mesh.levels.resize(vertices);
  std::vector<uint16_t> edges(vertices);
  std::vector<kernels::EdgeRef> corners(static_cast<std::size_t>(layout.corners()));
  kernels::MeshArrays out;
  out.positions_w = mesh.positions_w.data();
  out.normals_w = in.normals ? mesh.normals_w.data() : nullptr;
  out.colors = in.color ? mesh.colors.data() : nullptr;
  out.levels = mesh.levels.data();
  out.edges = edges.data();
  out.corners = corners.data();
  for (int32_t i = 0; i < n; ++i) kernels::write_block_mesh(view, *cache, in, i, *scratch, out);

  mesh.triangles.resize(corners.size() / 3);
  for (std::size_t k = 0; k < corners.size(); ++k) {
    const int64_t v = kernels::resolve_corner(in, edges.data(), corners[k]);
    r.unresolved += v < 0;
    mesh.triangles[k / 3][k % 3] = static_cast<int32_t>(v);
  }
  detail::merge_boundary_vertices(counts.data(), layout, mesh);
  r.mesh = detail::finish_mesh(std::move(mesh), params, map.params().voxel_size_m, nullptr);
  return r;
}

void expect_identical(const TriangleMesh& a, const TriangleMesh& b) {
  ASSERT_EQ(a.vertex_count(), b.vertex_count());
  ASSERT_EQ(a.triangle_count(), b.triangle_count());
  ASSERT_EQ(a.normals_w.size(), b.normals_w.size());
  ASSERT_EQ(a.colors.size(), b.colors.size());
  ASSERT_EQ(a.levels.size(), b.levels.size());
  for (std::size_t i = 0; i < a.positions_w.size(); ++i) {
    ASSERT_EQ(a.positions_w[i], b.positions_w[i]) << "vertex " << i;
    if (!a.normals_w.empty()) {
      ASSERT_EQ(a.normals_w[i], b.normals_w[i]) << "vertex " << i;
    }
    if (!a.colors.empty()) {
      ASSERT_EQ(a.colors[i], b.colors[i]) << "vertex " << i;
    }
    ASSERT_EQ(a.levels[i], b.levels[i]) << "vertex " << i;
  }
  for (std::size_t t = 0; t < a.triangles.size(); ++t)
    ASSERT_EQ(a.triangles[t], b.triangles[t]) << "triangle " << t;
}

/// The sphere on its floor fused at 4 mm into 3 levels (at the coarsest), then x >= 0 split to
/// the middle level and x >= 64 mm on to the finest, and fused again: blocks of all three
/// levels, and level boundaries where finer blocks meet coarser ones (vertices that no block
/// owns, made by each block that uses them).
std::unique_ptr<VoxelBlockMap> three_level_scene() {
  const test::SphereOnPlane scene;
  auto map = std::make_unique<VoxelBlockMap>(test::mesh_map_params(0.004f, 3, true, 0.048f));
  const Rgb8 color{200, 90, 30};
  test::fuse_views(*map, scene, 8, {0.5, 0.2}, &color);
  test::split_down(
      *map, 2, [](const BlockRef& b) { return b.pos.x >= (b.level == 2 ? 0 : 2); }, 0.0f);
  test::fuse_views(*map, scene, 8, {0.5, 0.2}, &color);
  return map;
}

TEST(MeshPasses, GiveExtractMeshsMeshAcrossLevels) {
  const auto map = three_level_scene();
  const std::vector<int64_t> per_level = map->blocks_per_level();
  for (const int64_t n : per_level) ASSERT_GT(n, 50) << ::testing::PrintToString(per_level);
  auto cases = test::mesh_param_cases();
  // A box through all three levels (x < 0 coarsest, [0, 64 mm) middle, beyond finest).
  cases.emplace_back("bounds", MeshParams{});
  cases.back().second.bounds = Box3f{{-0.25f, -0.3f, -0.01f}, {0.25f, 0.1f, 0.5f}};
  for (const auto& [name, params] : cases) {
    SCOPED_TRACE(name);
    const TriangleMesh reference = extract_mesh(*map, params);
    const PassesResult passes = mesh_in_passes(*map, params);
    EXPECT_EQ(passes.unresolved, 0);
    // Level boundaries: vertices made by several blocks, merged into one.
    EXPECT_GT(passes.boundary_vertices, 100);
    ASSERT_GT(reference.triangle_count(), 10000);
    if (params.bounds) {
      EXPECT_LT(reference.triangle_count(), extract_mesh(*map).triangle_count() * 9 / 10)
          << "the box cuts the surface";
    }
    expect_identical(reference, passes.mesh);
  }
}

// The tests' description of a vertex in its map (describe_vertex_in_map, used where two meshers
// disagree): the values it gives at the ends of the vertex's edge (the voxel of its level or, where
// that is split, of a finer one, or a coarser lattice's value at a level boundary) put a linear
// zero crossing where the vertex is.
TEST(MeshTestUtil, DescribesAVertexByItsEdgeAndTheMapsValues) {
  const auto map = three_level_scene();
  const TriangleMesh mesh = extract_mesh(*map);
  const std::regex end_re(R"(\[([^\]]*)\])");
  const std::regex value_re(R"((?:lattice|voxel) (-?[0-9.e+-]+))");
  const std::regex t_re(R"(, t (-?[0-9.e+-]+):)");
  int64_t checked = 0, with_lattice = 0;
  for (std::size_t v = 0; v < mesh.positions_w.size(); v += 7) {
    const std::string d = test::describe_vertex_in_map(*map, mesh.positions_w[v], mesh.levels[v]);
    std::smatch t_match;
    ASSERT_TRUE(std::regex_search(d, t_match, t_re)) << d;
    const double t = std::stod(t_match[1]);
    std::vector<std::vector<double>> ends;
    for (auto e = std::sregex_iterator(d.begin(), d.end(), end_re); e != std::sregex_iterator();
         ++e) {
      const std::string inside = (*e)[1];
      ends.emplace_back();
      for (auto x = std::sregex_iterator(inside.begin(), inside.end(), value_re);
           x != std::sregex_iterator(); ++x)
        // An exact 0 is meshed as kZeroTsdf (mesh_kernels.h).
        ends.back().push_back(std::stod((*x)[1]) == 0.0 ? kernels::kZeroTsdf : std::stod((*x)[1]));
    }
    ASSERT_EQ(ends.size(), 2u) << d;
    with_lattice += d.find("lattice") != std::string::npos;
    double closest = 1e9;
    for (double f0 : ends[0])
      for (double f1 : ends[1])
        if (f0 != f1) closest = std::min(closest, std::abs(t - f0 / (f0 - f1)));
    EXPECT_LT(closest, 1e-4) << d;
    ++checked;
  }
  EXPECT_GT(checked, 1000);
  EXPECT_GT(with_lattice, 10) << "level boundaries, sampled on the coarser lattice";
}

TEST(MeshPasses, AnEmptyMapGivesAnEmptyMesh) {
  const VoxelBlockMap map(test::mesh_map_params(0.01f, 2));
  const PassesResult r = mesh_in_passes(map, {});
  EXPECT_TRUE(r.mesh.empty());
  EXPECT_TRUE(r.mesh.triangles.empty());
  EXPECT_EQ(r.unresolved, 0);
}

TEST(MeshPasses, OwnedRankFindsOnlyListedEdges) {
  const std::vector<uint16_t> edges = {2, 5, 6, 40, 1535};
  for (std::size_t i = 0; i < edges.size(); ++i)
    EXPECT_EQ(kernels::owned_rank(edges.data(), 5, edges[i]), static_cast<int32_t>(i));
  for (const uint16_t missing : {0, 3, 7, 39, 41, 1534})
    EXPECT_EQ(kernels::owned_rank(edges.data(), 5, missing), -1) << missing;
  EXPECT_EQ(kernels::owned_rank(edges.data(), 0, 2), -1);
  // A count shorter than the list: the edges past it are not the block's.
  EXPECT_EQ(kernels::owned_rank(edges.data(), 3, 40), -1);
}

TEST(MeshPasses, ACornerWithoutItsVertexIsReported) {
  // Block 1's owned edges are {4, 9}; its vertices start at 10. Block 0 made 10 vertices.
  const std::vector<uint16_t> edges = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 4, 9};
  const std::vector<kernels::BlockMeshCount> counts = {{10, 10, 3}, {2, 2, 0}};
  const std::vector<int64_t> vertex_offset = {0, 10, 12};
  kernels::MeshPassInput in;
  in.counts = counts.data();
  in.vertex_offset = vertex_offset.data();
  EXPECT_EQ(kernels::resolve_corner(in, edges.data(), {1, 9}), 11);
  EXPECT_EQ(kernels::resolve_corner(in, edges.data(), {1, 5}), -1);
  EXPECT_EQ(kernels::resolve_corner(in, edges.data(), {0, kernels::kResolvedEdge | 7}), 7);
  EXPECT_EQ(kernels::resolve_corner(in, edges.data(), {1, kernels::kResolvedEdge | 1}), 11);
}

}  // namespace
}  // namespace hivox

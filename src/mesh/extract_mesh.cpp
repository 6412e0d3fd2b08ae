#include "hivox/mesh/extract_mesh.h"

#include <algorithm>
#include <atomic>
#include <limits>
#include <memory>
#include <numeric>
#include <tuple>

#include "core/parallel.h"
#include "hivox/core/error.h"
#include "mesh/mesh_passes.h"

namespace hivox {

namespace {

using kernels::EdgeRef;
using kernels::kResolvedEdge;

/// What one block contributes: the vertices on the edges it owns (ascending local edge id),
/// then those on edges of a level boundary that no block of its level owns, and its triangles
/// (3 corners each). Filled by kernels::mesh_block.
struct BlockMesh {
  static constexpr bool kVertices = true;
  std::vector<uint16_t> edges;
  std::vector<kernels::EdgeVertex> vertices;
  std::vector<EdgeRef> corners;

  void owned_vertex(uint16_t edge, const kernels::EdgeVertex& v) {
    edges.push_back(edge);
    vertices.push_back(v);
  }
  void boundary_vertex(const kernels::EdgeVertex& v) { vertices.push_back(v); }
  void corner(const EdgeRef& r) { corners.push_back(r); }
};

struct BlockScratch {
  kernels::BlockLookupCache cache;
  kernels::MeshBlockScratch mesh;
};

}  // namespace

namespace detail {

void merge_vertex_copies(std::vector<int32_t>& candidates, TriangleMesh& mesh) {
  const auto& pos = mesh.positions_w;
  std::sort(candidates.begin(), candidates.end(), [&](int32_t a, int32_t b) {
    const Vec3f &p = pos[static_cast<std::size_t>(a)], &q = pos[static_cast<std::size_t>(b)];
    return std::tie(p.x, p.y, p.z, a) < std::tie(q.x, q.y, q.z, b);
  });
  const std::size_t n = pos.size();
  std::vector<int32_t> target(n);
  std::iota(target.begin(), target.end(), 0);
  for (std::size_t k = 1; k < candidates.size(); ++k) {
    const int32_t a = candidates[k - 1], b = candidates[k];
    if (pos[static_cast<std::size_t>(a)] == pos[static_cast<std::size_t>(b)])
      target[static_cast<std::size_t>(b)] = target[static_cast<std::size_t>(a)];
  }
  // New indices: kept vertices in order; a copy takes its (earlier) original's.
  std::vector<int32_t> index(n);
  int32_t kept = 0;
  for (std::size_t v = 0; v < n; ++v) {
    if (target[v] != static_cast<int32_t>(v)) {
      index[v] = index[static_cast<std::size_t>(target[v])];
      continue;
    }
    index[v] = kept;
    auto move = [&](auto& attribute) {
      if (!attribute.empty()) attribute[static_cast<std::size_t>(kept)] = attribute[v];
    };
    move(mesh.positions_w);
    move(mesh.normals_w);
    move(mesh.colors);
    move(mesh.levels);
    ++kept;
  }
  auto shrink = [&](auto& attribute) {
    if (!attribute.empty()) attribute.resize(static_cast<std::size_t>(kept));
  };
  shrink(mesh.positions_w);
  shrink(mesh.normals_w);
  shrink(mesh.colors);
  shrink(mesh.levels);
  for (auto& t : mesh.triangles)
    for (int32_t& v : t) v = index[static_cast<std::size_t>(v)];
}

kernels::MeshPassInput mesh_pass_input(const MeshParams& params, bool map_color,
                                       const MeshBlocks& plan) {
  kernels::MeshPassInput in;
  in.blocks = plan.blocks.data();
  in.index_of_ptr = plan.index_of_ptr.data();
  in.cells = plan.cells.data();
  in.block_count = static_cast<int32_t>(plan.blocks.size());
  in.min_weight = static_cast<int>(params.min_weight);
  in.normals = params.compute_normals;
  in.color = params.with_color && map_color;
  in.table = &mc::kMcTable;
  return in;
}

MeshLayout mesh_layout(const kernels::BlockMeshCount* counts, int64_t blocks) {
  MeshLayout l;
  l.vertex_offset.assign(static_cast<std::size_t>(blocks) + 1, 0);
  l.corner_offset.assign(static_cast<std::size_t>(blocks) + 1, 0);
  for (int64_t i = 0; i < blocks; ++i) {
    l.vertex_offset[i + 1] = l.vertex_offset[i] + counts[i].vertices;
    l.corner_offset[i + 1] = l.corner_offset[i] + counts[i].corners;
  }
  if (l.vertices() > std::numeric_limits<int32_t>::max())
    fail(ErrorCode::OutOfCapacity, "mesh: {} vertices exceed the int32 index range", l.vertices());
  return l;
}

void merge_boundary_vertices(const kernels::BlockMeshCount* counts, const MeshLayout& layout,
                             TriangleMesh& mesh) {
  std::vector<int32_t> boundary;  // vertices on edges no block owns, made once per user
  const auto blocks = static_cast<int64_t>(layout.vertex_offset.size()) - 1;
  for (int64_t i = 0; i < blocks; ++i)
    for (int64_t v = layout.vertex_offset[i] + counts[i].owned; v < layout.vertex_offset[i + 1];
         ++v)
      boundary.push_back(static_cast<int32_t>(v));
  if (!boundary.empty()) merge_vertex_copies(boundary, mesh);
}

MeshBlocks plan_mesh_blocks(std::vector<BlockRef> allocated, int32_t high_water,
                            const MapParams& params, const std::optional<Box3f>& bounds,
                            const std::function<int32_t(int, const Vec3i&)>& ptr_of) {
  MeshBlocks plan;
  std::vector<BlockRef>& blocks = plan.blocks;
  blocks = std::move(allocated);
  std::sort(blocks.begin(), blocks.end(), [](const BlockRef& a, const BlockRef& b) {
    return BlockKey{a.pos, a.level} < BlockKey{b.pos, b.level};
  });
  if (!bounds) {
    plan.cells.assign(blocks.size(), 1);
  } else {
    // A block's neighbour: from the caller, or by binary search in the sorted list.
    auto find = [&](int level, const Vec3i& pos) -> int32_t {
      if (ptr_of) return ptr_of(level, pos);
      const BlockKey key{pos, level};
      const auto it = std::lower_bound(blocks.begin(), blocks.end(), key,
                                       [](const BlockRef& b, const BlockKey& k) {
                                         return BlockKey{b.pos, b.level} < k;
                                       });
      return it != blocks.end() && it->level == level && it->pos == pos ? it->ptr : -1;
    };
    const Box3f& box = *bounds;
    auto meets_box = [&](const BlockRef& b) {
      const float s = params.block_size_at(b.level);
      for (int a = 0; a < 3; ++a)
        if (static_cast<float>(b.pos[a]) * s > box.max_m[a] ||
            static_cast<float>(b.pos[a] + 1) * s + s / kBlockSide < box.min_m[a])
          return false;
      return true;
    };
    std::vector<uint8_t> keep(static_cast<std::size_t>(high_water), 0);
    for (const BlockRef& b : blocks) {
      if (!meets_box(b)) continue;
      keep[static_cast<std::size_t>(b.ptr)] = 2;  // cells and vertices
      for (int d = 1; d < 8; ++d) {
        const int32_t nb =
            find(b.level, {b.pos.x + (d & 1), b.pos.y + ((d >> 1) & 1), b.pos.z + (d >> 2)});
        if (nb >= 0 && keep[static_cast<std::size_t>(nb)] == 0)
          keep[static_cast<std::size_t>(nb)] = 1;  // vertices only
      }
    }
    std::erase_if(blocks,
                  [&](const BlockRef& b) { return keep[static_cast<std::size_t>(b.ptr)] == 0; });
    plan.cells.resize(blocks.size());
    for (std::size_t i = 0; i < blocks.size(); ++i)
      plan.cells[i] = keep[static_cast<std::size_t>(blocks[i].ptr)] == 2;
  }
  plan.index_of_ptr.assign(static_cast<std::size_t>(high_water), -1);
  for (std::size_t i = 0; i < blocks.size(); ++i)
    plan.index_of_ptr[static_cast<std::size_t>(blocks[i].ptr)] = static_cast<int32_t>(i);
  return plan;
}

TriangleMesh finish_mesh(TriangleMesh mesh, const MeshParams& params, float join_distance_m,
                         RemovedPieces* removed) {
  if (params.bounds) mesh = crop_mesh(mesh, *params.bounds);
  RemovedPieces r;
  if (params.min_piece_triangles > 0) {
    const int64_t before = mesh.triangle_count();
    mesh = remove_small_pieces(mesh, params.min_piece_triangles, join_distance_m, &r.pieces);
    r.triangles = before - mesh.triangle_count();
  }
  if (removed != nullptr) *removed = r;
  return mesh;
}

}  // namespace detail

namespace {

/// The CPU's extraction: blocks meshed in parallel, each thread with its own scratch.
TriangleMesh extract_mesh_cpu(const VoxelBlockMap& map, const MeshParams& params) {
  const MapView view = map.view();

  const detail::MeshBlocks plan = detail::plan_mesh_blocks(
      map.allocated_blocks(), map.block_high_water(), map.params(), params.bounds,
      [&](int level, const Vec3i& pos) { return find_block_ptr(view.level[level], pos); });
  const std::vector<BlockRef>& blocks = plan.blocks;
  const int64_t n = static_cast<int64_t>(blocks.size());
  const kernels::MeshPassInput in = detail::mesh_pass_input(params, view.color != nullptr, plan);

  // Pass 1: per block, its vertices and its triangles with corners as edge references.
  std::vector<BlockMesh> parts(static_cast<std::size_t>(n));
  parallel_team([&](const ThreadTeam& team) {
    const auto scratch = std::make_unique<BlockScratch>();  // per thread
    team.for_each(
        n,
        [&](int64_t i) {
          kernels::mesh_block(view, scratch->cache,
                              kernels::mesh_block_input(in, static_cast<int32_t>(i)), scratch->mesh,
                              parts[static_cast<std::size_t>(i)]);
        },
        CpuSchedule::dynamic(16));
  });

  // Pass 2: global numbering, block by block.
  std::vector<kernels::BlockMeshCount> counts(static_cast<std::size_t>(n));
  for (std::size_t i = 0; i < counts.size(); ++i)
    counts[i] = {static_cast<int32_t>(parts[i].edges.size()),
                 static_cast<int32_t>(parts[i].vertices.size()),
                 static_cast<int32_t>(parts[i].corners.size())};
  const detail::MeshLayout layout = detail::mesh_layout(counts.data(), n);
  const std::vector<int64_t>& vertex_offset = layout.vertex_offset;
  const int64_t vertices = layout.vertices();

  TriangleMesh mesh;
  mesh.positions_w.resize(static_cast<std::size_t>(vertices));
  if (params.compute_normals) mesh.normals_w.resize(static_cast<std::size_t>(vertices));
  if (in.color) mesh.colors.resize(static_cast<std::size_t>(vertices));
  mesh.levels.resize(static_cast<std::size_t>(vertices));
  mesh.triangles.resize(static_cast<std::size_t>(layout.corners() / 3));

  // Pass 3: copy vertices and resolve triangle corners (binary search in the owner's edges).
  std::atomic<int64_t> unresolved{0};
  parallel_for_dynamic(n, 64, [&](int64_t i) {
    BlockMesh& p = parts[static_cast<std::size_t>(i)];
    const int64_t v0 = vertex_offset[i];
    for (std::size_t k = 0; k < p.vertices.size(); ++k) {
      const kernels::EdgeVertex& v = p.vertices[k];
      const std::size_t dst = static_cast<std::size_t>(v0) + k;
      mesh.positions_w[dst] = v.position_w;
      if (params.compute_normals) mesh.normals_w[dst] = v.normal_w;
      if (in.color) mesh.colors[dst] = v.color;
      mesh.levels[dst] = static_cast<uint8_t>(blocks[i].level);
    }
    int64_t missing = 0;
    std::array<int32_t, 3>* out = mesh.triangles.data() + layout.corner_offset[i] / 3;
    for (std::size_t k = 0; k < p.corners.size(); ++k) {
      const EdgeRef r = p.corners[k];
      int64_t index;
      if (r.edge & kResolvedEdge) {
        index = vertex_offset[r.block] + (r.edge & ~kResolvedEdge);
      } else {
        const std::vector<uint16_t>& owner = parts[static_cast<std::size_t>(r.block)].edges;
        const int32_t rank =
            kernels::owned_rank(owner.data(), static_cast<int32_t>(owner.size()), r.edge);
        missing += rank < 0;
        index = vertex_offset[r.block] + std::max(rank, 0);
      }
      out[k / 3][k % 3] = static_cast<int32_t>(index);
    }
    if (missing) unresolved += missing;
  });
  // Owners decide about their edges from the same voxels and blocks as the cells that use them,
  // so every reference resolves; anything else is a bug, reported rather than meshed wrongly.
  if (unresolved.load() != 0)
    fail(ErrorCode::InvalidData, "mesh: {} triangle corners found no vertex (internal error)",
         unresolved.load());

  detail::merge_boundary_vertices(counts.data(), layout, mesh);
  return mesh;
}

}  // namespace

TriangleMesh extract_mesh(const VoxelBlockMap& map, const MeshParams& params,
                          RemovedPieces* removed) {
  params.validate();
  TriangleMesh mesh =
      dispatch(map.device(), "mesh extraction", [&] { return extract_mesh_cpu(map, params); });
  return detail::finish_mesh(std::move(mesh), params, map.params().voxel_size_m, removed);
}

}  // namespace hivox

// The allocation walk over the hierarchy (fusion_kernels.h: walk_segment) against a reference
// that samples the segment densely and looks every sample up from the coarsest level down.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <set>
#include <tuple>
#include <vector>

#include "fusion/fusion_kernels.h"
#include "hivox/map/voxel_block_map.h"
#include "map/split_util.h"

namespace hivox {
namespace {

using Key = std::tuple<int, int, int, int>;  // level, x, y, z

Key key_of(int level, const Vec3i& p) {
  return {level, p.x, p.y, p.z};
}

struct RecordingVisitor {
  const MapView& map;
  std::vector<Key> visits;
  int32_t block(int level, const Vec3i& pos) {
    visits.push_back(key_of(level, pos));
    return find_block_ptr(map.level[level], pos);
  }
};

// Three levels of 8/16/32 cm blocks over a 4x4x4 cube of coarsest blocks, about half of them
// split, and about half of those children split again; outside the cube nothing is stored.
std::unique_ptr<VoxelBlockMap> mixed_levels_map() {
  MapParams p;
  p.voxel_size_m = 0.01f;
  p.levels = 3;
  p.max_blocks = 1 << 14;
  p.buckets_per_level = 1 << 10;
  p.excess_per_level = 1 << 12;
  p.store_color = false;
  auto owned = std::make_unique<VoxelBlockMap>(p);
  VoxelBlockMap& map = *owned;
  std::vector<BlockKey> keys;
  for (int x = -2; x < 2; ++x)
    for (int y = -2; y < 2; ++y)
      for (int z = -2; z < 2; ++z) keys.push_back({{x, y, z}, 2});
  std::vector<BlockRef> top;
  map.insert_blocks(keys, &top);
  std::mt19937 rng(7);
  test::split_down(map, 2, [&rng](const BlockRef&) { return rng() % 2 == 0; });
  return owned;
}

// The blocks (with their Split ancestors) storing the points of the segment, sampled densely.
std::set<Key> reference_blocks(const MapView& map, const Vec3f& a, const Vec3f& b) {
  std::set<Key> out;
  const int samples = 20000;
  for (int i = 0; i <= samples; ++i) {
    const Vec3f p = a + (b - a) * (static_cast<float>(i) / samples);
    for (int l = map.levels - 1; l >= 0; --l) {
      const Vec3i c = block_of_point(map.level[l], p);
      out.insert(key_of(l, c));
      if (find_block_ptr(map.level[l], c) != kPtrSplit) break;
    }
  }
  return out;
}

// Length of segment a -> b inside block `k` grown by `margin` on every side (slab test), or -1
// when it does not meet the grown box.
float length_inside(const MapView& map, const Key& k, const Vec3f& a, const Vec3f& b,
                    float margin) {
  const auto [level, x, y, z] = k;
  const float size = map.level[level].block_size_m;
  const Vec3f lo{x * size - margin, y * size - margin, z * size - margin};
  const Vec3f hi{(x + 1) * size + margin, (y + 1) * size + margin, (z + 1) * size + margin};
  float t0 = 0, t1 = 1;
  for (int ax = 0; ax < 3; ++ax) {
    const float d = b[ax] - a[ax];
    if (std::abs(d) < 1e-12f) {
      if (a[ax] < lo[ax] || a[ax] > hi[ax]) return -1.0f;
      continue;
    }
    float ta = (lo[ax] - a[ax]) / d, tb = (hi[ax] - a[ax]) / d;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  if (t0 > t1) return -1.0f;
  const Vec3f d = b - a;
  return (t1 - t0) * std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
}

TEST(Walk, VisitsExactlyTheBlocksStoringTheSegmentAcrossLevels) {
  const auto map = mixed_levels_map();
  const MapView view = map->view();
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> pos(-0.75f, 0.75f), len(0.005f, 0.4f), unit(-1, 1);
  std::uniform_int_distribution<int> grid(-12, 12);
  int extra = 0, grazed = 0, segments = 0;
  for (int i = 0; i < 3000; ++i) {
    Vec3f a{pos(rng), pos(rng), pos(rng)};
    Vec3f dir{unit(rng), unit(rng), unit(rng)};
    if (i % 3 == 1) {  // start on block faces, edges and corners of the finest level
      a = {grid(rng) * 0.08f, grid(rng) * 0.08f, pos(rng)};
    } else if (i % 3 == 2) {  // along an axis
      dir = {0, 0, 0};
      dir[i % 7 % 3] = unit(rng) < 0 ? -1.0f : 1.0f;
    }
    const float n = std::sqrt(dir.x * dir.x + dir.y * dir.y + dir.z * dir.z);
    if (n < 1e-3f) continue;
    const Vec3f b = a + dir * (len(rng) / n);
    RecordingVisitor visitor{view, {}};
    kernels::walk_segment(view, a, b, visitor);
    ++segments;
    const std::set<Key> visited(visitor.visits.begin(), visitor.visits.end());
    EXPECT_EQ(visited.size(), visitor.visits.size()) << "a block visited twice, segment " << i;
    const std::set<Key> ref = reference_blocks(view, a, b);
    for (const Key& k : ref) {
      // Rounding at a face may shave a sliver off a block: a miss is allowed only where the
      // segment runs less than 1e-5 m inside the block.
      if (visited.count(k)) continue;
      ++grazed;
      EXPECT_LT(length_inside(view, k, a, b, 0.0f), 1e-5f)
          << "segment " << i << " misses block (level " << std::get<0>(k) << ")";
    }
    for (const Key& k : visited) {
      const auto [level, x, y, z] = k;
      // Visited only where that level is the one storing space: the parent is Split.
      if (level + 1 < view.levels) {
        const Vec3i parent{x >> 1, y >> 1, z >> 1};
        EXPECT_EQ(find_block_ptr(view.level[level + 1], parent), kPtrSplit) << "segment " << i;
      }
      // A block the dense samples missed is one the segment only grazes.
      if (!ref.count(k)) {
        ++extra;
        EXPECT_GE(length_inside(view, k, a, b, 1e-5f), 0.0f) << "segment " << i;
      }
    }
  }
  EXPECT_GT(segments, 2900);
  EXPECT_LT(extra, segments / 20) << "blocks visited beyond the dense reference";
  EXPECT_LT(grazed, segments / 100) << "blocks grazed but not visited";
}

}  // namespace
}  // namespace hivox

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

#include "hivox/map/voxel_block_map.h"
#include "map/map_access.h"
#include "map/sample_kernels.h"

namespace hivox {
namespace {

// A function of the interpolant's form with random coefficients.
struct TrilinearForm {
  float a[8];
  float operator()(const Vec3f& p) const {
    return a[0] * p.x * p.y * p.z + a[1] * p.x * p.y + a[2] * p.y * p.z + a[3] * p.x * p.z +
           a[4] * p.x + a[5] * p.y + a[6] * p.z + a[7];
  }
  Vec3f gradient(const Vec3f& p) const {
    return {a[0] * p.y * p.z + a[1] * p.y + a[3] * p.z + a[4],
            a[0] * p.x * p.z + a[1] * p.x + a[2] * p.z + a[5],
            a[0] * p.x * p.y + a[2] * p.y + a[3] * p.x + a[6]};
  }
};

TEST(IrregularInterpolation, ReproducesItsFormExactlyAtIrregularPositions) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> coef(-1.0f, 1.0f), jitter(-0.45f, 0.45f), in(0.0f, 1.0f);
  for (int trial = 0; trial < 200; ++trial) {
    TrilinearForm f;
    for (float& c : f.a) c = coef(rng);
    Vec3f pos[8];
    float val[8];
    const Vec3f offset{coef(rng) * 10, coef(rng) * 10, coef(rng) * 10};  // anywhere in space
    for (int c = 0; c < 8; ++c) {
      // Corners of a cube, each moved by up to 0.45: irregular but not degenerate.
      pos[c] = Vec3f{static_cast<float>(c & 1) + jitter(rng),
                     static_cast<float>((c >> 1) & 1) + jitter(rng),
                     static_cast<float>(c >> 2) + jitter(rng)} +
               offset;
      val[c] = f(pos[c]);
    }
    for (int k = 0; k < 5; ++k) {
      const Vec3f p = Vec3f{in(rng), in(rng), in(rng)} + offset;
      float got;
      Vec3f grad;
      ASSERT_TRUE(kernels::interpolate_irregular(pos, val, p, &got, &grad));
      EXPECT_NEAR(got, f(p), 2e-3f) << "trial " << trial;
      const Vec3f g = f.gradient(p);
      EXPECT_NEAR(grad.x, g.x, 5e-3f);
      EXPECT_NEAR(grad.y, g.y, 5e-3f);
      EXPECT_NEAR(grad.z, g.z, 5e-3f);
    }
  }
}

TEST(IrregularInterpolation, ReducesToTrilinearOnARegularCube) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> v(-1.0f, 1.0f), in(0.0f, 1.0f);
  for (int trial = 0; trial < 100; ++trial) {
    Vec3f pos[8];
    float val[8];
    for (int c = 0; c < 8; ++c) {
      pos[c] = {static_cast<float>(c & 1) + 5.0f, static_cast<float>((c >> 1) & 1) - 3.0f,
                static_cast<float>(c >> 2) + 7.0f};
      val[c] = v(rng);
    }
    const Vec3f t{in(rng), in(rng), in(rng)};
    Vec3f g_tri, g_irr;
    const float tri = kernels::interpolate_trilinear(val, t, &g_tri);
    float irr;
    ASSERT_TRUE(kernels::interpolate_irregular(pos, val, t + pos[0], &irr, &g_irr));
    EXPECT_NEAR(irr, tri, 1e-5f);
    EXPECT_NEAR(g_irr.x, g_tri.x, 1e-4f);
    EXPECT_NEAR(g_irr.y, g_tri.y, 1e-4f);
    EXPECT_NEAR(g_irr.z, g_tri.z, 1e-4f);
  }
}

// The ray's segment inside the unit cell around t: [s_in, s_out] in ray parameter.
void segment_in_cell(const Vec3f& t, const Vec3f& dv, float* s_in, float* s_out) {
  *s_in = -1e30f;
  *s_out = 1e30f;
  for (int k = 0; k < 3; ++k) {
    if (dv[k] == 0.0f) continue;
    const float a = -t[k] / dv[k], b = (1.0f - t[k]) / dv[k];
    *s_in = std::max(*s_in, std::min(a, b));
    *s_out = std::min(*s_out, std::max(a, b));
  }
}

Vec3f random_direction(std::mt19937& rng, float scale) {
  std::normal_distribution<float> n(0.0f, 1.0f);
  Vec3f d{n(rng), n(rng), n(rng)};
  return d * (scale / norm(d));
}

TEST(CrossingInCell, ThePlaneOfALinearTsdfIsHitExactly) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> in(0.0f, 1.0f), offset(-0.8f, 0.8f), speed(0.2f, 3.0f);
  int found = 0, checked = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    // F(u) = n . (u - c) / 2: a plane through the cell (TSDF units, a slope below 1 per voxel).
    const Vec3f n = random_direction(rng, 1.0f);
    const Vec3f c{0.5f + offset(rng), 0.5f + offset(rng), 0.5f + offset(rng)};
    float v[8];
    for (int k = 0; k < 8; ++k) {
      const Vec3f corner{static_cast<float>(k & 1), static_cast<float>((k >> 1) & 1),
                         static_cast<float>(k >> 2)};
      v[k] = 0.5f * dot(n, corner - c);
    }
    const Vec3f t{in(rng), in(rng), in(rng)};
    const Vec3f dv = random_direction(rng, speed(rng));
    float s_in, s_out;
    segment_in_cell(t, dv, &s_in, &s_out);
    // The exact crossing, and whether it is a front face on the side the sign at t calls for.
    const float f_t = 0.5f * dot(n, t - c), slope = 0.5f * dot(n, dv);
    const float s_star = -f_t / slope;
    const bool front = slope < 0.0f;
    const bool expected = front && (f_t > 0.0f ? s_star <= s_out : s_star >= s_in);
    // Crossings within rounding of the segment's ends may go either way.
    if (std::fabs(s_star - s_in) < 1e-4f || std::fabs(s_star - s_out) < 1e-4f) continue;
    ++checked;
    float dz;
    Vec3f t_hit;
    const bool hit =
        kernels::crossing_in_cell(v, t, dv, kernels::inverse_direction(dv), &dz, &t_hit);
    ASSERT_EQ(hit, expected) << "trial " << trial << " f(t) " << f_t << " s* " << s_star
                             << " segment [" << s_in << ", " << s_out << "]";
    if (!hit) continue;
    ++found;
    EXPECT_NEAR(dz, s_star, 2e-5f) << "trial " << trial;
    EXPECT_NEAR(t_hit.x, t.x + dv.x * s_star, 2e-5f);
    EXPECT_NEAR(t_hit.y, t.y + dv.y * s_star, 2e-5f);
    EXPECT_NEAR(t_hit.z, t.z + dv.z * s_star, 2e-5f);
  }
  EXPECT_GT(checked, 1900);
  EXPECT_GT(found, 300);  // the trials are not all misses
}

TEST(CrossingInCell, FindsTheSignChangeOfAnyCell) {
  // Arbitrary corner values: the interpolant along the ray is a general cubic. A crossing is
  // reported exactly when the values at t and at the end of the segment on the side the sign at
  // t calls for change sign, and the root found is one (|F| tiny, between those two points).
  std::mt19937 rng(8);
  std::uniform_real_distribution<float> value(-1.0f, 1.0f), in(0.0f, 1.0f), speed(0.2f, 3.0f);
  int found = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    float v[8];
    for (float& x : v) x = value(rng);
    const Vec3f t{in(rng), in(rng), in(rng)};
    const Vec3f dv = random_direction(rng, speed(rng));
    float s_in, s_out;
    segment_in_cell(t, dv, &s_in, &s_out);
    auto f_at = [&](float s) {
      Vec3f unused;
      return kernels::interpolate_trilinear(v, t + dv * s, &unused);
    };
    const float f_t = f_at(0.0f);
    const float s_end = f_t > 0.0f ? s_out : s_in;
    const float f_end = f_at(s_end);
    // Values within rounding of zero at the bracket's ends may go either way.
    if (std::fabs(f_t) < 1e-4f || std::fabs(f_end) < 1e-4f) continue;
    const bool expected = f_t > 0.0f ? f_end <= 0.0f : f_end > 0.0f;
    float dz;
    Vec3f t_hit;
    const bool hit =
        kernels::crossing_in_cell(v, t, dv, kernels::inverse_direction(dv), &dz, &t_hit);
    ASSERT_EQ(hit, expected) << "trial " << trial;
    if (!hit) continue;
    ++found;
    EXPECT_GE(dz, std::min(0.0f, s_end) - 1e-5f) << "trial " << trial;
    EXPECT_LE(dz, std::max(0.0f, s_end) + 1e-5f) << "trial " << trial;
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(t_hit[k], t[k] + dv[k] * dz, 1e-5f);
    // A root lies within 0.005 voxel of the one reported (these cubics are far more curved than
    // a TSDF's, and the few steps taken leave a small residual on some).
    const float ds = 0.005f / norm(dv);
    EXPECT_TRUE(f_at(dz) == 0.0f || (f_at(dz - ds) > 0.0f && f_at(dz + ds) <= 0.0f))
        << "trial " << trial << " F " << f_at(dz);
  }
  EXPECT_GT(found, 500);
}

TEST(IrregularInterpolation, DegenerateConfigurationsAreRejectedWithoutNaN) {
  Vec3f pos[8];
  float val[8];
  for (int c = 0; c < 8; ++c) {
    pos[c] = {static_cast<float>(c & 1), static_cast<float>((c >> 1) & 1),
              static_cast<float>(c >> 2)};
    val[c] = static_cast<float>(c);
  }
  // Two samples at the same place (two corners took the same coarse voxel).
  Vec3f twice[8];
  std::copy(pos, pos + 8, twice);
  twice[3] = twice[1];
  float f = 12345.0f;
  Vec3f g{7, 7, 7};
  EXPECT_FALSE(kernels::interpolate_irregular(twice, val, {0.5f, 0.5f, 0.5f}, &f, &g));
  EXPECT_EQ(f, 12345.0f) << "outputs untouched: the caller falls back";
  // All samples on a plane.
  Vec3f flat[8];
  for (int c = 0; c < 8; ++c) flat[c] = {pos[c].x, pos[c].y, 0.0f};
  EXPECT_FALSE(kernels::interpolate_irregular(flat, val, {0.5f, 0.5f, 0.5f}, &f, &g));
  // Pivoting matters: sample 1 lies on the x = 0 plane with sample 0, which makes the first
  // pivot candidate zero for a solver without row exchanges; with pivoting it solves.
  Vec3f tricky[8] = {{0, 0, 0}, {0, 1.2f, 0.3f}, {1, 0, 0},    {1, 1, 0},
                     {0, 0, 1}, {1, 0, 1},       {0.1f, 1, 1}, {1, 1, 1}};
  TrilinearForm form{{0.3f, -0.2f, 0.5f, 0.1f, 1.0f, -1.0f, 0.25f, 0.7f}};
  float tv[8];
  for (int c = 0; c < 8; ++c) tv[c] = form(tricky[c]);
  ASSERT_TRUE(kernels::interpolate_irregular(tricky, tv, {0.4f, 0.6f, 0.5f}, &f, &g));
  EXPECT_NEAR(f, form({0.4f, 0.6f, 0.5f}), 1e-4f);
  EXPECT_FALSE(std::isnan(f));
}

// Two levels (1 cm / 2 cm): level-1 block (0, 0, 0) stored, level-1 block (1, 0, 0) split into
// its 8 level-0 children. Every voxel holds the linear function F(X, Y, Z) = 3X - 5Y + 7Z + 11
// (int16 units) of its position in level-0 voxel units, so any interpolation on either lattice
// must give F exactly.
int lattice_f(int x, int y, int z) {
  return 3 * x - 5 * y + 7 * z + 11;
}

// `coarse` level-1 blocks stored as such, `split` ones stored through their 8 level-0 children.
std::unique_ptr<VoxelBlockMap> lattice_map(const std::vector<Vec3i>& coarse,
                                           const std::vector<Vec3i>& split) {
  MapParams mp;
  mp.voxel_size_m = 0.01f;
  mp.levels = 2;
  mp.max_blocks = 64;
  auto map = std::make_unique<VoxelBlockMap>(mp);
  std::vector<BlockKey> keys;
  for (const Vec3i& b : coarse) keys.push_back({b, 1});
  for (const Vec3i& b : split) {
    keys.push_back({b, 1});
    for (int c = 0; c < 8; ++c)
      keys.push_back({{2 * b.x + (c & 1), 2 * b.y + ((c >> 1) & 1), 2 * b.z + (c >> 2)}, 0});
  }
  std::vector<BlockRef> inserted;
  map->insert_blocks(keys, &inserted);
  EXPECT_EQ(inserted.size(), keys.size());
  for (const BlockRef& b : inserted) {
    const int k = b.level == 1 ? 2 : 1;  // level-0 voxels per voxel of the block's level
    TsdfVoxel* vox = MapAccess::tsdf(*map, b.ptr);
    for (int i = 0; i < kBlockVoxels; ++i) {
      const Vec3i c = voxel_coords(i);
      vox[i].tsdf = static_cast<int16_t>(
          lattice_f(k * (b.pos.x * 8 + c.x), k * (b.pos.y * 8 + c.y), k * (b.pos.z * 8 + c.z)));
      vox[i].weight = 2;
    }
    MapAccess::refresh_surface(*map, b.ptr);
  }
  const LevelView lv = map->view().level[1];
  HashEntry* entries = MapAccess::storage(*map).level[1].entries;
  for (const Vec3i& b : split) entries[find_entry(lv, b)].ptr = kPtrSplit;
  return map;
}

std::unique_ptr<VoxelBlockMap> split_lattice_map() {
  return lattice_map({{0, 0, 0}}, {{1, 0, 0}});
}

// Level-1 blocks (0, 0, 0) and (0, 1, 0) split, (1, 0, 0) coarse, (1, 1, 0) split again: the
// last fine cells before the coarse block, x in [15, 16) (level-0 units), reach across levels.
std::unique_ptr<VoxelBlockMap> boundary_lattice_map() {
  return lattice_map({{1, 0, 0}}, {{0, 0, 0}, {0, 1, 0}, {1, 1, 0}});
}

TEST(LatticeSampling, FineCellsReachingIntoACoarseRegionKeepALinearFieldExact) {
  // Level-1 block 0 split (level-0 x in [0, 16)), level-1 block (1, 0, 0) coarse (x in [16,
  // 32)) and block (1, 1, 0) split again. The last fine cells, x in [15, 16), take their x = 16
  // corners from the coarse voxels. Where a cell's y or z corners are 2j - 1 and 2j, rounding both
  // to the nearest coarse voxel put them on one sample and the cell fell back to trilinear on
  // misplaced values: off by up to half a coarse voxel's change of F. Taken on the corner's side,
  // the samples stay distinct and the interpolant, which holds every linear function, gives F
  // exactly. At y in [14, 16) the sample beyond y = 15 lies in the split block (1, 1, 0), whose
  // fine voxel at y = 16 stands in for it.
  const auto map = boundary_lattice_map();
  const MapView view = map->view();
  auto cache = std::make_unique<kernels::BlockLookupCache>();
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  double worst = 0.0;
  int irregular = 0, beyond = 0;
  for (int i = 0; i < 4000; ++i) {
    // Level-0 voxel units; z below 14, where the coarse samples beyond stay in block (1, 0, 0).
    const Vec3f q{15.0f + u(rng), 16.0f * u(rng), 14.0f * u(rng)};
    kernels::TsdfSample s;
    ASSERT_TRUE(kernels::sample_trilinear(view, *cache, 0, q * 0.01f, 1, &s)) << q.y;
    const float exact = (3.0f * q.x - 5.0f * q.y + 7.0f * q.z + 11.0f) / kTsdfScale;
    worst = std::max(worst, std::abs(static_cast<double>(s.f - exact)) * kTsdfScale);
    irregular += (static_cast<int>(q.y) % 2 == 1) || (static_cast<int>(q.z) % 2 == 1);
    beyond += q.y >= 14.0f;
  }
  EXPECT_GT(irregular, 2000);
  EXPECT_GT(beyond, 200);
  EXPECT_LT(worst, 0.05) << "largest error, int16 TSDF units (F changes by 3-7 per voxel)";
}

TEST(LatticeSampling, ARayFindsItsCrossingInsideACellAcrossLevels) {
  // The map of the test above, its linear field's plane F = 0 through the last fine cells before
  // the coarse block (x in [15, 16), level-0 units). A ray sampled in such a cell, its corners
  // partly coarse, finds where it crosses the plane inside the cell as a cell within one level
  // does (TsdfSample::crossing_dz), on the cell's interpolant: the irregular one, which holds the
  // linear field exactly, or the trilinear one where the coarse samples stand on the lattice. A
  // ray's search near a level boundary then ends at its first sample, as elsewhere.
  const auto map = boundary_lattice_map();
  const MapView view = map->view();
  auto cache = std::make_unique<kernels::BlockLookupCache>();
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const Vec3f normal = normalized(Vec3f{3.0f, -5.0f, 7.0f});  // F's gradient
  int checked = 0;
  double worst = 0.0;
  const int64_t irregular_before = cache->irregular_cells;
  for (int i = 0; i < 2000; ++i) {
    // A point of the plane in a cell x in [15, 16), and a ray through it from the plane's front.
    const float x = 15.05f + 0.9f * u(rng), z = 3.2f * u(rng);
    const Vec3f hit{x, (3.0f * x + 7.0f * z + 11.0f) / 5.0f, z};
    Vec3f d = normalized(Vec3f{u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f});
    if (dot(d, normal) > 0.0f) d = d * -1.0f;
    if (dot(d, normal) > -0.2f) continue;  // not grazing
    // Sampled a little before or after the crossing, in the same cell.
    const float s0 = (u(rng) - 0.5f) * 0.6f;  // level-0 voxels along the ray
    const Vec3f q = hit - d * s0;
    if (!(floor_to_int(q) == floor_to_int(hit))) continue;
    kernels::TsdfSample s;
    // The ray in metres: `d` metres per unit of ray parameter.
    ASSERT_TRUE(kernels::sample_trilinear(view, *cache, 0, q * 0.01f, 1, &s, Vec3i{INT_MIN, 0, 0},
                                          kPtrEmpty, nullptr, &d));
    ASSERT_TRUE(s.at_crossing()) << "sampled " << s0 << " voxels before the crossing";
    const Vec3f found = q + d * (s.crossing_dz / 0.01f);
    worst = std::max(worst, static_cast<double>(norm(found - hit)));
    EXPECT_NEAR(s.f, 0.0f, 0.05f / kTsdfScale);
    ++checked;
  }
  EXPECT_GT(checked, 500);
  EXPECT_GT(cache->irregular_cells - irregular_before, 100);
  EXPECT_LT(worst, 0.01) << "level-0 voxels from the plane's crossing";
}

TEST(LatticeSampling, CoarseLatticePointsInASplitRegionReadTheFinerVoxel) {
  const auto map = split_lattice_map();
  const MapView view = map->view();
  auto cache = std::make_unique<kernels::BlockLookupCache>();
  for (int x = 0; x < 16; ++x)  // level-1 coordinates across both level-1 blocks
    for (int y = 0; y < 8; y += 3) {
      int32_t ptr = -1;
      Vec3i voxel;
      const int level = kernels::lattice_voxel(view, *cache, 1, {x, y, 5}, &ptr, &voxel);
      ASSERT_EQ(level, x < 8 ? 1 : 0) << x;
      EXPECT_EQ(map->block_meta(ptr).level, level);
      EXPECT_EQ(voxel, (level == 1 ? Vec3i{x, y, 5} : Vec3i{2 * x, 2 * y, 10}));
      EXPECT_EQ(view.tsdf[static_cast<int64_t>(ptr) * kBlockVoxels + local_voxel_index(voxel)].tsdf,
                lattice_f(2 * x, 2 * y, 10));
    }
  int32_t ptr;
  Vec3i voxel;
  EXPECT_EQ(kernels::lattice_voxel(view, *cache, 1, {16, 0, 0}, &ptr, &voxel), -1);
  EXPECT_EQ(kernels::lattice_voxel(view, *cache, 1, {-1, 0, 0}, &ptr, &voxel), -1);
  // A level-0 point inside the coarse block: its nearest level-1 voxel.
  ASSERT_EQ(kernels::lattice_voxel(view, *cache, 0, {5, 2, 9}, &ptr, &voxel), 1);
  EXPECT_EQ(voxel, (Vec3i{3, 1, 5}));
}

TEST(LatticeSampling, FinePointsTakeTheCoarseLatticesInterpolantExactly) {
  const auto map = split_lattice_map();
  const MapView view = map->view();
  auto cache = std::make_unique<kernels::BlockLookupCache>();
  for (int x = 0; x < 32; ++x)
    for (int y = 0; y < 16; ++y)
      for (int z = 0; z < 16; z += 5) {
        float f = 0;
        int32_t ptr = -1;
        int index = -1;
        const bool ok = kernels::sample_on_coarser_lattice(view, *cache, 0, {x, y, z}, 1, 1.0f, &f,
                                                           &ptr, &index);
        // The coarse cell around an odd coordinate reaches one coarse voxel further, which is
        // stored only below 32 (x) and 16 (y, z) level-0 units.
        const bool reachable =
            (x % 2 == 0 || x < 31) && (y % 2 == 0 || y < 15) && (z % 2 == 0 || z < 15);
        ASSERT_EQ(ok, reachable) << x << " " << y << " " << z;
        if (!ok) continue;
        EXPECT_NEAR(f, tsdf_to_float(static_cast<int16_t>(lattice_f(x, y, z))), 1e-7f)
            << x << " " << y << " " << z;
        ASSERT_GE(ptr, 0);
      }
  // Not enough observations: a corner that contributes has weight 2 < 3.
  float f;
  int32_t ptr;
  int index;
  EXPECT_FALSE(
      kernels::sample_on_coarser_lattice(view, *cache, 0, {3, 4, 4}, 1, 3.0f, &f, &ptr, &index));
}

}  // namespace
}  // namespace hivox

#pragma once
// Ray marching through the TSDF, written once for the CPU and CUDA drivers.

#include <cfloat>
#include <climits>

#include "hivox/core/atomic.h"
#include "hivox/core/camera.h"
#include "hivox/core/hd.h"
#include "hivox/core/image.h"
#include "hivox/core/math.h"
#include "hivox/map/map_view.h"
#include "hivox/raycast/params.h"
#include "map/sample_kernels.h"
#include "raycast/coarse_occupancy.h"

namespace hivox::kernels {

/// Where a raycast's rays start at the nearest: `min_depth_m`, but no nearer than 1 mm (blocks
/// at the camera's centre project without bound).
HIVOX_HD inline float nearest_ray_start(float min_depth_m) {
  constexpr float kNearest_m = 1e-3f;
  return min_depth_m > kNearest_m ? min_depth_m : kNearest_m;
}

/// Ray parameter where ray o + z d leaves the axis-aligned block `b` of side `block_m`.
HIVOX_HD inline float block_exit(const Vec3f& o, const Vec3f& d, const Vec3i& b, float block_m) {
  float t = FLT_MAX;
  for (int k = 0; k < 3; ++k) {
    if (d[k] > 0.0f) {
      const float tk = (static_cast<float>(b[k] + 1) * block_m - o[k]) / d[k];
      t = tk < t ? tk : t;
    } else if (d[k] < 0.0f) {
      const float tk = (static_cast<float>(b[k]) * block_m - o[k]) / d[k];
      t = tk < t ? tk : t;
    }
  }
  return t;
}

/// Ray parameter where ray o + z d leaves the box [lo, hi), given 1 / d per axis.
HIVOX_HD inline float box_exit(const Vec3f& o, const Vec3f& d, const Vec3f& inv_d, const Vec3f& lo,
                               const Vec3f& hi) {
  float t = FLT_MAX;
  for (int k = 0; k < 3; ++k) {
    if (d[k] == 0.0f) continue;
    const float tk = ((d[k] > 0.0f ? hi[k] : lo[k]) - o[k]) * inv_d[k];
    t = tk < t ? tk : t;
  }
  return t;
}

/// The unit normal from the TSDF one voxel ahead along each axis (samples_one_voxel_ahead) and
/// the value `f_at_p` at the point: forward differences; at a surface point F = 0.
HIVOX_HD inline Vec3f normal_from_ahead(const Vec3f& ahead, float f_at_p) {
  return normalized(ahead - Vec3f{f_at_p, f_at_p, f_at_p});
}

/// Surface normal at a surface point `p_w` (unit, pointing to free space) from differences of
/// the interpolated TSDF one voxel apart. At a surface point F = 0, so forward differences need
/// only 3 samples; spanning a voxel they are smoother than the gradient of a single
/// interpolation cell, which follows per-voxel noise. Where those samples' voxels are not all
/// stored at `level` (a level boundary, or voxels not yet observed), the normal is `at_hit`, the
/// gradient of the hit's own interpolant: across levels, the irregular interpolant spans the
/// coarse samples around the hit. Three more samples across levels took ~13 % of a model
/// raycast's warps' time on fr1/rpy (`bench/ray_cost`); the gradient gave the same trajectory and
/// fewer speckles at level borders (docs/cuda.md).
HIVOX_HD HIVOX_DEVICE_NOINLINE inline Vec3f tsdf_normal(const MapView& map, BlockLookupCache& cache,
                                                        const Vec3f& p_w, float f_at_p, int level,
                                                        int min_weight, const Vec3f& at_hit) {
  Vec3f ahead;
  if (samples_one_voxel_ahead(map, cache, level, p_w, min_weight, &ahead))
    return normal_from_ahead(ahead, f_at_p);
  return normalized(at_hit);
}

struct RayMarchConstants {
  float mu_m = 0;             ///< truncation band
  float step_fraction = 0;    ///< of the TSDF distance per step
  float min_step_voxels = 2;  ///< smallest step in front of a surface, voxels of its level
  int min_weight = 1;
  CoarseOccupancy occupancy;   ///< optional (empty: unallocated space is crossed block by block)
  float hint_margin_m = 0;     ///< a hinted ray's march starts this far in front of its hint
  float hint_agreement_m = 0;  ///< hints this close search the fallback first (ray_hints)
};

/// The constants of a raycast of `map` with `p` (the same for every driver).
inline RayMarchConstants march_constants(const RaycastParams& p, const MapView& map,
                                         const CoarseOccupancy& occupancy) {
  RayMarchConstants k;
  k.mu_m = map.truncation_m;
  k.step_fraction = p.step_fraction;
  k.min_weight = p.min_weight;
  k.occupancy = occupancy;
  const float coarsest_voxel_m = map.level[map.levels - 1].voxel_size_m;
  k.min_step_voxels = fminf(2.0f, 0.5f * map.truncation_m / coarsest_voxel_m + 0.5f);
  k.hint_margin_m = p.hint_margin_mu * map.truncation_m;
  k.hint_agreement_m = p.hint_agreement_mu * map.truncation_m;
  return k;
}

struct RayHit {
  float depth_m = 0;  ///< ray parameter (depth along the optical axis for camera rays)
  Vec3f p_w;
  Vec3f normal_w;
  int level = 0;
  int32_t color_ptr = kPtrEmpty;
  int color_index = 0;
};

/// A crossing bracketed by z_lo (TSDF > 0) and z_hi (<= 0), refined by secant steps until the
/// bracket spans at most a voxel (`voxel_z`, in ray parameter) or `kMaxSteps` samples were
/// taken, or until a sample finds the crossing inside its cell (the samples are taken with the
/// ray, see TsdfSample::crossing_dz), which ends it `exact`. `best` is the last sample that
/// succeeded (initially the one at z_hi), `level` its level. The scalar refinement
/// (`refine_crossing`) and the CPU driver's ray packets take the same steps.
struct CrossingBracket {
  static constexpr int kMaxSteps = 4;
  float z_lo = 0, f_lo = 0, z_hi = 0, f_hi = 0;
  float voxel_z = 0;
  TsdfSample best;
  int level = 0;
  int steps = 0;
  bool exact = false;  ///< z_lo = z_hi is the crossing, found inside the cell of `best`
};

/// `b` := the bracket (z_lo, f_lo) .. (z_hi, f_hi), `at_hi` the sample at z_hi (level
/// `level_hi`). Written in place: a bracket built aside and copied into a packet's array costs a
/// stalled copy per ray.
HIVOX_HD inline void make_bracket(const MapView& map, const Vec3f& d, float z_lo, float f_lo,
                                  float z_hi, float f_hi, const TsdfSample& at_hi, int level_hi,
                                  CrossingBracket* b) {
  b->z_lo = z_lo;
  b->f_lo = f_lo;
  b->z_hi = z_hi;
  b->f_hi = f_hi;
  b->voxel_z = map.level[level_hi].voxel_size_m / norm(d);
  b->best = at_hi;
  b->level = level_hi;
  b->steps = 0;
  b->exact = false;
}

/// `b` := the bracket of a crossing that sample `s`, taken at `z` (level `level`), found inside
/// its cell (s.at_crossing()): the usual end of a hinted ray's search.
HIVOX_HD inline void exact_bracket(const MapView& map, const Vec3f& d, float z, const TsdfSample& s,
                                   int level, CrossingBracket* b) {
  const float z_hit = z + s.crossing_dz;
  make_bracket(map, d, z_hit, s.f, z_hit, s.f, s, level, b);
  b->exact = true;
}

/// Where the secant through the bracket's ends crosses zero: the next sample, and the hit.
HIVOX_HD inline float bracket_secant(const CrossingBracket& b) {
  return b.exact ? b.z_lo : b.z_lo + (b.z_hi - b.z_lo) * b.f_lo / (b.f_lo - b.f_hi);
}

/// Takes the sample at `bracket_secant(b)` (`sampled` false: it failed). Returns true when the
/// refinement is done. One step is usual: the TSDF is close to linear across a short bracket and
/// each step costs a full interpolation; more follow when the bracket is long.
HIVOX_HD inline bool bracket_update(CrossingBracket& b, float zm, bool sampled,
                                    const TsdfSample& sm, int level_m) {
  if (!sampled) return true;
  b.best = sm;
  b.level = level_m;
  if (sm.at_crossing()) {
    b.exact = true;
    b.z_lo = b.z_hi = zm + sm.crossing_dz;
    return true;
  }
  if (sm.f > 0.0f) {
    b.z_lo = zm;
    b.f_lo = sm.f;
  } else {
    b.z_hi = zm;
    b.f_hi = sm.f;
  }
  return ++b.steps >= CrossingBracket::kMaxSteps || b.z_hi - b.z_lo <= b.voxel_z;
}

/// Fills the hit of a refined bracket except its normal.
HIVOX_HD inline void bracket_hit(const CrossingBracket& b, const Vec3f& o, const Vec3f& d,
                                 RayHit* hit) {
  const float z_hit = bracket_secant(b);
  hit->depth_m = z_hit;
  hit->p_w = o + d * z_hit;
  hit->level = b.level;
  hit->color_ptr = b.best.nearest_ptr;
  hit->color_index = b.best.nearest_index;
}

/// Refines bracket `b` with secant steps (see CrossingBracket) and fills the hit.
HIVOX_HD HIVOX_DEVICE_NOINLINE inline void refine_bracket(const MapView& map,
                                                          BlockLookupCache& cache, const Vec3f& o,
                                                          const Vec3f& d, CrossingBracket b,
                                                          const RayMarchConstants& k, RayHit* hit) {
  while (!b.exact) {
    const float zm = bracket_secant(b);
    TsdfSample sm;
    int lm;
    const bool sampled = sample_tsdf(map, cache, o + d * zm, k.min_weight, &sm, &lm, &d, b.level);
    if (bracket_update(b, zm, sampled, sm, lm)) break;
  }
  bracket_hit(b, o, d, hit);
  hit->normal_w =
      tsdf_normal(map, cache, hit->p_w, 0.0f, hit->level, k.min_weight, b.best.gradient);
}

/// Refines a crossing bracketed by z_lo (TSDF > 0) and z_hi (<= 0) with secant steps until the
/// bracket spans at most a voxel, and fills the hit. `fallback` is the sample at z_hi (used if
/// refinement samples fail).
HIVOX_HD HIVOX_DEVICE_NOINLINE inline void refine_crossing(
    const MapView& map, BlockLookupCache& cache, const Vec3f& o, const Vec3f& d, float z_lo,
    float f_lo, float z_hi, float f_hi, const TsdfSample& fallback, int fallback_level,
    const RayMarchConstants& k, RayHit* hit) {
  CrossingBracket b;
  make_bracket(map, d, z_lo, f_lo, z_hi, f_hi, fallback, fallback_level, &b);
  refine_bracket(map, cache, o, d, b, k, hit);
}

/// A crossing bracketed from behind (back_to_crossing): a positive sample in front, the negative
/// one behind it.
struct BackBracket {
  float z_pos = 0, f_pos = 0, z_neg = 0;
  TsdfSample neg;
  int neg_level = 0;
};

/// The crossing in front of `s`, a sample at `z` behind a surface (-1 < s.f <= 0, level
/// `level`), found by following the sample's gradient back along the ray: where it puts the
/// crossing, half a voxel in front, a sample on the positive side brackets it with the last
/// negative one (`*b`, for refine_crossing). Where that sample falls on unobserved voxels (a
/// sliver of them can part the positive side from the negative, beside a level boundary), 1.5 and
/// then 3 voxels in front: a positive sample there brackets the crossing across the sliver. At
/// most two steps; false where the gradient does not fall along the ray, a step leaves
/// [z_start, z) or finds no observed voxels. The caller refines the bracket.
HIVOX_HD inline bool back_to_crossing(const MapView& map, BlockLookupCache& cache, const Vec3f& o,
                                      const Vec3f& d, float z, const TsdfSample& s, int level,
                                      float z_start, const RayMarchConstants& k, BackBracket* b) {
  b->neg = s;
  b->neg_level = level;
  b->z_neg = z;
  for (int i = 0; i < 2; ++i) {
    const float voxel_m = map.level[b->neg_level].voxel_size_m;
    const float slope = dot(b->neg.gradient, d) / voxel_m;  // dF per unit of ray parameter
    if (!(slope < 0.0f)) return false;
    // Where the gradient puts the values of half a voxel, then 1.5 and 3 voxels, in front of the
    // surface (a voxel is voxel_m / mu in TSDF units), whatever the ray's incidence: an
    // unobserved voxel layer leaves the cells of two voxels unknown.
    constexpr float kInFront[3] = {0.5f, 1.5f, 3.0f};
    const float f_voxel = voxel_m / k.mu_m;
    TsdfSample t;
    int lt;
    bool sampled = false;
    float z_try = b->z_neg;
    for (int j = 0; j < 3 && !sampled; ++j) {
      z_try = b->z_neg - (b->neg.f - kInFront[j] * f_voxel) / slope;
      if (!(z_try >= z_start && z_try < b->z_neg)) return false;
      sampled =
          sample_tsdf(map, cache, o + d * z_try, k.min_weight, &t, &lt, nullptr, b->neg_level);
    }
    if (!sampled) return false;
    if (t.f > 0.0f) {
      b->z_pos = z_try;
      b->f_pos = t.f;
      return true;
    }
    b->neg = t;
    b->neg_level = lt;
    b->z_neg = z_try;
  }
  return false;
}

/// The crossing in front of `s`, the sample at `z` (level `level`) where a march came from
/// skipped or unobserved space straight into the band behind a surface (-1 < s.f <= 0): first
/// where the sample's gradient puts it (back_to_crossing: the positive side can be thinner than
/// the steps below where unobserved voxels lie in front of it), then at 1, 2, 4 and 8 voxels back
/// (along a ray at a grazing angle the positive side can lie several voxels back), then along the
/// gradient again from the frontmost negative sample met (nearer the crossing where the first
/// one lay where the band flattens). Refines the crossing into `hit` and returns true where it
/// finds one.
HIVOX_HD inline bool search_back_for_crossing(const MapView& map, BlockLookupCache& cache,
                                              const Vec3f& o, const Vec3f& d, float z,
                                              const TsdfSample& s, int level, float z_start,
                                              const RayMarchConstants& k, RayHit* hit) {
  const float inv_len = 1.0f / norm(d);
  BackBracket back;
  bool behind = back_to_crossing(map, cache, o, d, z, s, level, z_start, k, &back);
  float back_m = map.level[level].voxel_size_m;
  float z_front = z;  // the frontmost negative sample met (sampled again where it is needed)
  for (int i = 0; i < 4 && !behind; ++i, back_m *= 2.0f) {
    const float z_back = z - back_m * inv_len;
    if (z_back < z_start) break;
    TsdfSample sb;
    int lb;
    if (!sample_tsdf(map, cache, o + d * z_back, k.min_weight, &sb, &lb, nullptr, level)) continue;
    if (sb.f > 0.0f) {
      refine_crossing(map, cache, o, d, z_back, sb.f, z, s.f, s, level, k, hit);
      return true;
    }
    if (sb.f > -1.0f) z_front = z_back;
  }
  if (!behind && z_front < z) {
    TsdfSample front;
    int front_level;
    behind = sample_tsdf(map, cache, o + d * z_front, k.min_weight, &front, &front_level, nullptr,
                         level) &&
             back_to_crossing(map, cache, o, d, z_front, front, front_level, z_start, k, &back);
  }
  if (!behind) return false;
  refine_crossing(map, cache, o, d, back.z_pos, back.f_pos, back.z_neg, back.neg.f, back.neg,
                  back.neg_level, k, hit);
  return true;
}

/// What a march saw on its way, besides its hit (march_ray's optional report).
struct MarchReport {
  bool known = false;           ///< it met observed voxels (a sample, or an observed free octant)
  bool started_behind = false;  ///< the first of them lay behind a surface, no crossing before
};

/// Marches ray `o + z d` for z in [z_start, z_end] to the first crossing of the TSDF from
/// positive (free space) to negative. Through unallocated space it jumps from block to block;
/// through known space it steps by the TSDF distance, through unknown voxels by the band; the
/// crossing is refined by the secant method.
/// `report` (optional) receives what the march met: where it started behind a surface, one in
/// front of z_start is likely.
/// `z_first` (when > z_start): where the march begins, the ray in front of it known to cross no
/// cell with a surface (RayStretch); a sample just behind a surface still searches back into it
/// (as far as z_start). The march finds what it would find from z_start. `stop_if_behind`: the
/// march ends (false) where it finds it started behind a surface.
HIVOX_HD HIVOX_DEVICE_NOINLINE inline bool march_ray(const MapView& map, BlockLookupCache& cache,
                                                     const Vec3f& o, const Vec3f& d, float z_start,
                                                     float z_end, const RayMarchConstants& k,
                                                     RayHit* hit, MarchReport* report = nullptr,
                                                     float z_first = 0.0f,
                                                     bool stop_if_behind = false) {
  MarchReport unused;
  MarchReport& seen = report != nullptr ? *report : unused;
  const float inv_len = 1.0f / norm(d);
  const Vec3f inv_d{d.x != 0.0f ? 1.0f / d.x : 0.0f, d.y != 0.0f ? 1.0f / d.y : 0.0f,
                    d.z != 0.0f ? 1.0f / d.z : 0.0f};
  const float band_step_m = k.mu_m * k.step_fraction;
  float z = z_first > z_start ? z_first : z_start;
  float prev_z = z, prev_f = 0.0f;
  bool prev_valid = false;
  TsdfSample s;
  // The block the ray is in; looked up again only when the ray leaves its bounds.
  int level = 0;
  Vec3i pos;
  int32_t ptr = kPtrEmpty;
  Vec3f lo{1.0f, 1.0f, 1.0f}, hi{0.0f, 0.0f, 0.0f};  // empty: forces the first look-up
  NeighbourBlocks neighbours;                        // of the cells that reach beyond the block
  int stored_level = -1;
  while (z <= z_end) {
    const Vec3f p = o + d * z;
    if (!((p.x >= lo.x) & (p.y >= lo.y) & (p.z >= lo.z) & (p.x < hi.x) & (p.y < hi.y) &
          (p.z < hi.z))) {
      // The box the ray is in: an empty super-block (no block of any level: one step across)
      // or the block stored here.
      const Vec3i super_block = k.occupancy.cell_of(p);
      float side_m;
      if (k.occupancy.empty(super_block)) {
        ptr = kPtrEmpty;
        level = map.levels - 1;
        side_m = k.occupancy.side_m;
        lo = to_float(super_block) * side_m;
      } else {
        ptr = locate_block(map, cache, p, &level, &pos, stored_level);
        stored_level = ptr >= 0 ? level : -1;
        side_m = map.level[level].block_size_m;
        lo = to_float(pos) * side_m;
      }
      hi = Vec3f{lo.x + side_m, lo.y + side_m, lo.z + side_m};
    }
    // Nothing stored here, or no cell of this block (or of the octant of it the ray is in) with
    // an observed corner at or behind a surface (all positive: no crossing inside): skip to
    // where the ray leaves it. A surface just beyond the exit is caught by the look-back below.
    Vec3f skip_lo = lo, skip_hi = hi;
    bool skip = ptr < 0;
    if (!skip) {
      const BlockSurface surface = map.meta[ptr].surface;
      const float half_m = 0.5f * (hi.x - lo.x);
      const int ox = p.x >= lo.x + half_m, oy = p.y >= lo.y + half_m, oz = p.z >= lo.z + half_m;
      const unsigned bit = 1u << (ox | (oy << 1) | (oz << 2));
      if (surface.surface == 0) {
        skip = true;
      } else if ((surface.surface & bit) == 0) {
        skip = true;
        skip_lo = {lo.x + static_cast<float>(ox) * half_m, lo.y + static_cast<float>(oy) * half_m,
                   lo.z + static_cast<float>(oz) * half_m};
        skip_hi = {skip_lo.x + half_m, skip_lo.y + half_m, skip_lo.z + half_m};
        // Observed and all positive: known free space in front, as a positive sample would say.
        seen.known = seen.known || (surface.observed & bit) != 0;
      }
    }
    if (skip) {
      const float exit = box_exit(o, d, inv_d, skip_lo, skip_hi);
      const float min_step = 1e-3f * map.level[level].voxel_size_m * inv_len;
      z = step_beyond(z, exit > z + min_step ? exit + min_step : z + min_step);
      prev_valid = false;
      continue;
    }
    const float voxel_m = map.level[level].voxel_size_m;
    if (!sample_trilinear(map, cache, level, p, k.min_weight, &s, pos, ptr, &neighbours)) {
      if (prev_valid && prev_f > 0.0f) {
        // The step left known space: the negative band behind a surface can be thinner than a
        // step where the back is unobserved. Bisect back towards the last positive sample.
        float z_lo = prev_z, f_lo = prev_f, z_hi = z;
        for (int i = 0; i < 3; ++i) {
          const float zm = 0.5f * (z_lo + z_hi);
          TsdfSample sm;
          int lm;
          if (!sample_tsdf(map, cache, o + d * zm, k.min_weight, &sm, &lm, nullptr, level)) {
            z_hi = zm;  // still unknown: the crossing, if any, is nearer
            continue;
          }
          if (sm.f <= 0.0f) {
            refine_crossing(map, cache, o, d, z_lo, f_lo, zm, sm.f, sm, lm, k, hit);
            return hit->depth_m <= z_end;
          }
          z_lo = zm;
          f_lo = sm.f;
        }
      }
      // Unobserved voxels: no surface can be here; move on as through free space.
      z = step_beyond(z, z + (band_step_m > voxel_m ? band_step_m : voxel_m) * inv_len);
      prev_valid = false;
      continue;
    }
    if (s.f <= 0.0f && !seen.known) {
      seen.started_behind = true;
      if (stop_if_behind) return false;
    }
    seen.known = true;
    if (s.f <= 0.0f) {
      if (prev_valid && prev_f > 0.0f) {
        refine_crossing(map, cache, o, d, prev_z, prev_f, z, s.f, s, level, k, hit);
        return hit->depth_m <= z_end;
      }
      // Came from skipped or unknown space straight into the band behind a surface: search back
      // for the positive side.
      if (!prev_valid && s.f > -1.0f &&
          search_back_for_crossing(map, cache, o, d, z, s, level, z_start, k, hit))
        return hit->depth_m <= z_end;
    }
    prev_valid = true;
    prev_f = s.f;
    prev_z = z;
    // Step by the distance the TSDF promises (scaled down: projective distances overestimate),
    // but at least `min_step_voxels` (the crossing is bracketed and refined afterwards; the
    // negative band behind a surface is mu deep, so no crossing is stepped over); behind a
    // surface, by a voxel.
    const float min_step_m = k.min_step_voxels * voxel_m;
    const float dist_m = s.f > 0.0f ? s.f * band_step_m : voxel_m;
    z = step_beyond(z, z + (dist_m > min_step_m ? dist_m : min_step_m) * inv_len);
  }
  return false;
}

/// The search for the surface near a ray's measured depth `z_hint` (the frame that measured it
/// was just fused from the ray's pose): Newton steps from a sample at the hint, first along the
/// slope of the interpolant's gradient, then along the secant of the last two samples, each
/// carried half a voxel beyond the predicted crossing, until two consecutive samples bracket the
/// crossing. Where the gradient does not fall along the ray, the slope of a projective TSDF fused
/// from this pose is taken: -1 per `mu_m` of depth (`d` has unit depth). A sample that fails
/// (unobserved voxels, typically just behind a surface seen from one side only) is taken again
/// halfway back towards the last good one. Samples are taken with the ray: one whose cell holds
/// the crossing (usually the first, at the hint) ends the search with the exact crossing.
/// `hit_near_hint` runs it ray by ray; the CPU driver's ray packets take the same steps.
struct HintSearch {
  static constexpr int kMaxSamples = 8;
  float z0 = 0;  ///< the last sample's ray parameter
  TsdfSample s0;
  int l0 = 0;
  float slope = 0;  ///< dF/dz
  float half_voxel_z = 0, max_step = 0;
  int samples = 1;
  float retry_z = -1.0f;  ///< where to sample next after a failed sample (negative: none)
};

/// Starts the search from the sample `s0` (level `l0`) at the hint; false when that sample is
/// truncated (no crossing within the band).
HIVOX_HD inline bool hint_search_begin(const MapView& map, const Vec3f& d, float z_hint,
                                       const TsdfSample& s0, int l0, const RayMarchConstants& k,
                                       HintSearch* h) {
  if (s0.f >= 1.0f || s0.f <= -1.0f) return false;
  const float inv_len = 1.0f / norm(d);
  h->z0 = z_hint;
  h->s0 = s0;
  h->l0 = l0;
  h->half_voxel_z = 0.5f * map.level[l0].voxel_size_m * inv_len;
  h->max_step = k.mu_m * inv_len;
  h->slope = dot(s0.gradient, d) * map.level[l0].inv_voxel_size;
  h->samples = 1;
  h->retry_z = -1.0f;
  return true;
}

/// The ray parameter of the next sample.
HIVOX_HD inline float hint_search_next(HintSearch& h, const RayMarchConstants& k) {
  if (h.retry_z >= 0.0f) return h.retry_z;
  const float projective = -1.0f / k.mu_m;
  if (!(h.slope < 0.1f * projective)) h.slope = projective;
  float step = -h.s0.f / h.slope;
  step += step > 0.0f ? h.half_voxel_z : -h.half_voxel_z;
  step = step > h.max_step ? h.max_step : (step < -h.max_step ? -h.max_step : step);
  return h.z0 + step;
}

enum class HintStep { Continue, Bracketed, GiveUp };

/// Takes the sample at `z1 = hint_search_next(h)` (`sampled` false: it failed). On `Bracketed`,
/// `bracket` holds the crossing; on `GiveUp` the caller marches instead.
HIVOX_HD inline HintStep hint_search_update(HintSearch& h, const MapView& map, const Vec3f& d,
                                            float z1, bool sampled, const TsdfSample& s1, int l1,
                                            CrossingBracket* bracket) {
  ++h.samples;
  if (!sampled) {
    if (h.samples >= HintSearch::kMaxSamples) return HintStep::GiveUp;
    h.retry_z = 0.5f * (h.z0 + z1);
    return HintStep::Continue;
  }
  h.retry_z = -1.0f;
  if (s1.at_crossing()) {
    exact_bracket(map, d, z1, s1, l1, bracket);
    return HintStep::Bracketed;
  }
  // The slope is negative, so steps go forward from free space and back from behind a
  // surface: a sign change always brackets a front face, free space in front.
  if ((h.s0.f > 0.0f) != (s1.f > 0.0f)) {
    if (h.s0.f > 0.0f)
      make_bracket(map, d, h.z0, h.s0.f, z1, s1.f, s1, l1, bracket);
    else
      make_bracket(map, d, z1, s1.f, h.z0, h.s0.f, h.s0, h.l0, bracket);
    return HintStep::Bracketed;
  }
  if (s1.f == h.s0.f || h.samples >= HintSearch::kMaxSamples) return HintStep::GiveUp;
  h.slope = (s1.f - h.s0.f) / (z1 - h.z0);
  h.z0 = z1;
  h.s0 = s1;
  h.l0 = l1;
  return HintStep::Continue;
}

/// Finds the surface at a ray's measured depth `z_hint` (see HintSearch) and refines it by the
/// secant method. Returns false when no bracket is found within a few samples (the caller
/// marches instead). `start_level`: where the first sample's look-up starts (locate_block).
HIVOX_HD HIVOX_DEVICE_NOINLINE inline bool hit_near_hint(const MapView& map,
                                                         BlockLookupCache& cache, const Vec3f& o,
                                                         const Vec3f& d, float z_hint,
                                                         const RayMarchConstants& k, RayHit* hit,
                                                         int start_level = -1) {
  TsdfSample s;
  int l;
  if (!sample_tsdf(map, cache, o + d * z_hint, k.min_weight, &s, &l, &d, start_level)) return false;
  CrossingBracket b;
  if (s.at_crossing()) {
    exact_bracket(map, d, z_hint, s, l, &b);  // the usual case: the surface is in the hint's cell
  } else {
    HintSearch h;
    if (!hint_search_begin(map, d, z_hint, s, l, k, &h)) return false;
    for (;;) {
      const float z1 = hint_search_next(h, k);
      const bool sampled = sample_tsdf(map, cache, o + d * z1, k.min_weight, &s, &l, &d, l);
      const HintStep step = hint_search_update(h, map, d, z1, sampled, s, l, &b);
      if (step == HintStep::GiveUp) return false;
      if (step == HintStep::Bracketed) break;
    }
  }
  refine_bracket(map, cache, o, d, b, k, hit);
  return true;
}

/// The stretch [z_in, z_out] of a ray outside which it crosses no cell where it could meet a
/// surface (SurfaceTiles::ray_stretch); by default the whole ray.
struct RayStretch {
  float z_in = 0.0f;
  float z_out = FLT_MAX;
};

/// A march split across the lanes of a GPU warp: the warp takes the rays whose hints failed one
/// at a time, each lane marching a stretch of the ray, instead of each thread marching its own
/// ray while its warp waits for the longest. Lane `lane` of `lanes` marches its stretch of
/// [z_start, z_end]: the stretches are equal, at least `kMinStretchBands` bands long (a short
/// march uses fewer lanes; the others march nothing), and each reaches a band into the next, so
/// that one lane brackets a crossing at a boundary; a lane that starts behind a surface
/// searches back as far as z_start. The march's hit is the lowest lane's (split_march_result).
struct LaneMarch {
  static constexpr float kMinStretchBands = 4.0f;
  bool found = false;
  RayHit hit;
  MarchReport report;
};
HIVOX_HD inline LaneMarch march_lane(const MapView& map, BlockLookupCache& cache, const Vec3f& o,
                                     const Vec3f& d, float z_start, float z_end,
                                     const RayMarchConstants& k, int lane, int lanes) {
  LaneMarch m;
  const float band = k.mu_m;
  float length = (z_end - z_start) / static_cast<float>(lanes);
  length =
      length > LaneMarch::kMinStretchBands * band ? length : LaneMarch::kMinStretchBands * band;
  const float from = z_start + static_cast<float>(lane) * length;
  if (from > z_end) return m;
  const float to = from + length + band;
  m.found =
      march_ray(map, cache, o, d, z_start, to < z_end ? to : z_end, k, &m.hit, &m.report, from);
  return m;
}

/// The lowest set bit's index of `mask` (not 0).
HIVOX_HD inline int lowest_lane(uint32_t mask) {
#if defined(__CUDA_ARCH__)
  return __ffs(static_cast<int>(mask)) - 1;
#else
  return __builtin_ctz(mask);
#endif
}

/// A split march's result from its lanes' reports as masks (bit i: lane i): the winner is the
/// lowest lane that found a crossing (-1: none); the march began behind a surface where the
/// lowest lane that met observed voxels began behind one.
struct SplitMarch {
  int winner = -1;
  bool behind = false;
};
HIVOX_HD inline SplitMarch split_march_result(uint32_t found, uint32_t known, uint32_t behind) {
  SplitMarch r;
  if (found != 0u) r.winner = lowest_lane(found);
  if (known != 0u) r.behind = ((behind >> lowest_lane(known)) & 1u) != 0u;
  return r;
}

/// The stretches of march_from_hint as a split march takes them: first `far` (from the hint's
/// margin, or z_min without a hint, to z_max); where that finds nothing or began behind a
/// surface and there is a hint, `front` (z_min to the hint), whose hit wins where it has one.
struct HintStretches {
  float far_from = 0, far_to = 0, front_from = 0, front_to = 0;
  HIVOX_HD bool has_front() const { return front_to > 0.0f; }
};
HIVOX_HD inline HintStretches hint_stretches(float hint, float z_min, float z_max,
                                             const RayMarchConstants& k) {
  HintStretches s;
  s.far_from = hint > 0.0f ? hint - k.hint_margin_m : z_min;
  s.far_to = z_max;
  if (hint > 0.0f) {
    s.front_from = z_min;
    s.front_to = hint < z_max ? hint : z_max;
  }
  return s;
}

/// The march of a ray whose hint search failed, or that has no hint (`hint` 0): from
/// `k.hint_margin_m` in front of the hint (from `z_min` without one) to `z_max`. Where the hint is
/// wrong (a model surface in front of it, e.g. at a depth edge, or none behind it), the part in
/// front of the hint is searched as well. Both marches skip what lies outside `stretch`.
HIVOX_HD inline bool march_from_hint(const MapView& map, BlockLookupCache& cache, const Vec3f& o,
                                     const Vec3f& d, float hint, float z_min, float z_max,
                                     const RayMarchConstants& k, RayHit* hit,
                                     const RayStretch& stretch = {}) {
  MarchReport behind;
  auto end_at = [&](float z_end) { return z_end < stretch.z_out ? z_end : stretch.z_out; };
  const HintStretches st = hint_stretches(hint, z_min, z_max, k);
  // With a hint, the march behind it stops as soon as it finds it began behind a surface: the
  // march in front of the hint decides then, and the march behind runs whole only where that
  // finds nothing. The same hit as marching behind first, without its cost where the front wins
  // (the slowest rays of a raycast were often these: a hint behind a depth edge, marched to the
  // end of the range before the front was searched).
  bool found = march_ray(map, cache, o, d, st.far_from, end_at(st.far_to), k, hit, &behind,
                         stretch.z_in, st.has_front());
  if (st.has_front() && (!found || behind.started_behind)) {
    RayHit front;
    if (march_ray(map, cache, o, d, st.front_from, end_at(st.front_to), k, &front, nullptr,
                  stretch.z_in)) {
      *hit = front;
      return true;
    }
    if (behind.started_behind)
      found = march_ray(map, cache, o, d, st.far_from, end_at(st.far_to), k, hit, nullptr,
                        stretch.z_in);
  }
  return found;
}

/// Which lane's hit a split march_from_hint keeps: `front` says from which stretch, `winner` the
/// lane (-1: the ray hit nothing).
struct SplitChoice {
  bool front = false;
  int winner = -1;
};
/// march_from_hint's decisions for a split march. `march(from, to, front)` marches that stretch
/// split across the lanes (each lane keeping its own LaneMarch of each stretch) and returns
/// their split_march_result; a GPU warp's lanes call this together, a CPU emulation once for
/// all lanes.
template <typename SplitMarchFn>
HIVOX_HD inline SplitChoice split_march_from_hint(const HintStretches& st, SplitMarchFn&& march) {
  const SplitMarch far = march(st.far_from, st.far_to, false);
  if (st.has_front() && (far.winner < 0 || far.behind)) {
    const SplitMarch front = march(st.front_from, st.front_to, true);
    if (front.winner >= 0) return {true, front.winner};
  }
  return {false, far.winner};
}

/// A split march_from_hint on the CPU, lane after lane (what the raycast tests check against the
/// whole march): what a warp's `lanes` lanes find together for one ray, with `caches[lane]`
/// each. Returns whether the ray hit, into `hit`.
inline bool split_march_on_cpu(const MapView& map, BlockLookupCache* caches, const Vec3f& o,
                               const Vec3f& d, float hint, float z_min, float z_max,
                               const RayMarchConstants& k, int lanes, RayHit* hit) {
  constexpr int kMostLanes = 32;
  LaneMarch far[kMostLanes], front[kMostLanes];
  lanes = lanes < kMostLanes ? lanes : kMostLanes;
  auto march = [&](float from, float to, bool is_front) {
    LaneMarch* m = is_front ? front : far;
    uint32_t found = 0, known = 0, behind = 0;
    for (int lane = 0; lane < lanes; ++lane) {
      m[lane] = march_lane(map, caches[lane], o, d, from, to, k, lane, lanes);
      found |= static_cast<uint32_t>(m[lane].found) << lane;
      known |= static_cast<uint32_t>(m[lane].report.known) << lane;
      behind |= static_cast<uint32_t>(m[lane].report.started_behind) << lane;
    }
    return split_march_result(found, known, behind);
  };
  const SplitChoice c = split_march_from_hint(hint_stretches(hint, z_min, z_max, k), march);
  if (c.winner < 0) return false;
  *hit = (c.front ? front : far)[c.winner].hit;
  return true;
}

/// Where a ray's surface was found (see cast_ray).
enum class RayOutcome { Miss, AtHint, AtSecondHint, Marched };

/// A pixel's two hints (see Raycaster::raycast): `hint` is the start hint, or where it has none
/// the fallback; `second` the fallback where it differs from `hint`. Where the two lie within
/// `k.hint_agreement_m` of each other, the other way round: both point at one surface, and the
/// fallback (a previous raycast) says where the model holds it. A depth counts only where a
/// start `k.hint_margin_m` in front of it lies inside the pixel's range (z_min, z_max).
struct RayHints {
  float hint = 0;
  float second = 0;
  bool hint_is_fallback = false;  ///< `hint` comes from the fallback (`second`, if any, not)
  /// The level the surface near the hints is likely stored at (the pixel's last hit, say): the
  /// search's first look-up starts there (locate_block); -1: at the coarsest level.
  int level = -1;

  /// Whether a ray with these hints that ended with `outcome` found its surface at the fallback.
  HIVOX_HD bool found_at_fallback(RayOutcome outcome) const {
    return (outcome == RayOutcome::AtHint && hint_is_fallback) ||
           (outcome == RayOutcome::AtSecondHint && !hint_is_fallback);
  }
};
HIVOX_HD inline RayHints ray_hints(float start_m, float fallback_m, const RayMarchConstants& k,
                                   float z_min, float z_max) {
  auto in_range = [&](float z) {
    return z > 0.0f && z - k.hint_margin_m > z_min && z - k.hint_margin_m < z_max ? z : 0.0f;
  };
  RayHints h;
  h.hint = in_range(start_m);
  h.second = in_range(fallback_m);
  if (h.hint == 0.0f) {
    h.hint = h.second;
    h.hint_is_fallback = h.hint > 0.0f;
    h.second = 0.0f;
  } else if (h.second == h.hint) {
    h.second = 0.0f;
  } else if (h.second > 0.0f && fabsf(h.second - h.hint) <= k.hint_agreement_m) {
    const float start = h.hint;
    h.hint = h.second;
    h.second = start;
    h.hint_is_fallback = true;
  }
  return h;
}

/// One pixel's ray searched alone near its hints: the surface near the hint, else near the
/// second hint; Miss when both fail (or there are none), where the caller marches. Hits beyond
/// z_max do not count.
HIVOX_HD inline RayOutcome search_at_hints(const MapView& map, BlockLookupCache& cache,
                                           const Vec3f& o, const Vec3f& d, const RayHints& hints,
                                           float z_max, const RayMarchConstants& k, RayHit* hit) {
  auto near = [&](float hint) {
    return hint > 0.0f && hit_near_hint(map, cache, o, d, hint, k, hit, hints.level) &&
           hit->depth_m <= z_max;
  };
  if (near(hints.hint)) return RayOutcome::AtHint;  // usually: the surface is at the depth fused
  if (near(hints.second)) return RayOutcome::AtSecondHint;
  return RayOutcome::Miss;
}

/// One pixel's ray, searched alone (a GPU thread's ray): search_at_hints, else a march over
/// [z_min, z_max] (march_from_hint). Hits beyond z_max do not count.
HIVOX_HD inline RayOutcome cast_ray(const MapView& map, BlockLookupCache& cache, const Vec3f& o,
                                    const Vec3f& d, const RayHints& hints, float z_min, float z_max,
                                    const RayMarchConstants& k, RayHit* hit) {
  const RayOutcome at_hints = search_at_hints(map, cache, o, d, hints, z_max, k, hit);
  if (at_hints != RayOutcome::Miss) return at_hints;
  if (z_max > 0.0f && march_from_hint(map, cache, o, d, hints.hint, z_min, z_max, k, hit))
    return RayOutcome::Marched;
  return RayOutcome::Miss;
}

/// The raycast's output images as plain arrays (one element per pixel, row-major).
struct RaycastOutputView {
  float* depth_m = nullptr;
  Vec3f* points_w = nullptr;
  Vec3f* normals_w = nullptr;
  Rgb8* colors = nullptr;
  int8_t* levels = nullptr;
};

/// Writes pixel `i`: the hit, or no surface (depth 0, level -1, the rest zero).
HIVOX_HD inline void write_ray(const RaycastOutputView& out, const MapView& map, int64_t i,
                               bool found, const RayHit& hit) {
  if (!found) {
    out.depth_m[i] = 0.0f;
    out.points_w[i] = {};
    out.normals_w[i] = {};
    out.colors[i] = {};
    out.levels[i] = -1;
    return;
  }
  out.depth_m[i] = hit.depth_m;
  out.points_w[i] = hit.p_w;
  out.normals_w[i] = hit.normal_w;
  out.levels[i] = static_cast<int8_t>(hit.level);
  if (map.color != nullptr && hit.color_ptr >= 0) {
    const ColorVoxel c =
        map.color[static_cast<int64_t>(hit.color_ptr) * kBlockVoxels + hit.color_index];
    out.colors[i] = {c.r, c.g, c.b};
  } else {
    out.colors[i] = {};
  }
}

// ---- range image ----------------------------------------------------------------------------

struct RangeTiles {
  float* z_min = nullptr;  ///< per tile, initialised to +large
  float* z_max = nullptr;  ///< per tile, initialised to 0
  int tiles_x = 0, tiles_y = 0, tile_px = 8;
  /// The planes through the camera centre and the image's borders, x = s z and y = s z (camera
  /// frame), and sqrt(1 + s^2) for each: box_tile_rect's quick test.
  float x_lo = 0, x_hi = 0, y_lo = 0, y_hi = 0;
  float x_lo_len = 1, x_hi_len = 1, y_lo_len = 1, y_hi_len = 1;

  /// The tiles of `tile_px` pixels covering the image of `cam` (z_min, z_max unset).
  HIVOX_HD static RangeTiles covering(int tile_px, const PinholeCamera& cam) {
    RangeTiles t;
    t.tile_px = tile_px;
    t.tiles_x = (cam.width + tile_px - 1) / tile_px;
    t.tiles_y = (cam.height + tile_px - 1) / tile_px;
    t.x_lo = (-0.5f - cam.cx) / cam.fx;
    t.x_hi = (static_cast<float>(cam.width) - 0.5f - cam.cx) / cam.fx;
    const float y_a = (-0.5f - cam.cy) / cam.fy;
    const float y_b = (static_cast<float>(cam.height) - 0.5f - cam.cy) / cam.fy;
    t.y_lo = y_a < y_b ? y_a : y_b;  // fy < 0 flips the image
    t.y_hi = y_a < y_b ? y_b : y_a;
    t.x_lo_len = sqrtf(1.0f + t.x_lo * t.x_lo);
    t.x_hi_len = sqrtf(1.0f + t.x_hi * t.x_hi);
    t.y_lo_len = sqrtf(1.0f + t.y_lo * t.y_lo);
    t.y_hi_len = sqrtf(1.0f + t.y_hi * t.y_hi);
    return t;
  }
  HIVOX_HD int count() const { return tiles_x * tiles_y; }
  HIVOX_HD int tile_of(int x, int y) const { return (y / tile_px) * tiles_x + x / tile_px; }
};

/// The range tiles (and depths) the box [origin, origin + side_m]^3 covers seen by `cam` from
/// `T_cw`: tiles tx0..tx1 by ty0..ty1, depths z_lo..z_hi clamped to [min_depth_m, max_depth_m].
struct TileRect {
  int tx0 = 0, ty0 = 0, tx1 = -1, ty1 = -1;
  float z_lo = 0, z_hi = 0;
};

/// Projects the box's corners (see TileRect); false when the box is outside the view or the
/// depth range.
HIVOX_HD inline bool box_tile_rect(const Rigid3f& T_cw, const PinholeCamera& cam,
                                   const Vec3f& origin, float side_m, float min_depth_m,
                                   float max_depth_m, const RangeTiles& tiles, TileRect* rect) {
  // First the box's bounding sphere against the depth range and the planes through the camera
  // centre and the image's borders: most blocks of a large map are out of view, and this costs
  // a fraction of projecting 8 corners.
  const float half_m = 0.5f * side_m;
  const Vec3f c = T_cw * Vec3f{origin.x + half_m, origin.y + half_m, origin.z + half_m};
  const float r = 1.7320508f * half_m;
  if (c.z + r < min_depth_m || c.z - r > max_depth_m) return false;
  // Outside a plane x = s z (likewise y) by more than r: (x - s z) / sqrt(1 + s^2) < -r.
  if (c.x - tiles.x_lo * c.z < -r * tiles.x_lo_len ||
      tiles.x_hi * c.z - c.x < -r * tiles.x_hi_len ||
      c.y - tiles.y_lo * c.z < -r * tiles.y_lo_len || tiles.y_hi * c.z - c.y < -r * tiles.y_hi_len)
    return false;
  float u_lo = FLT_MAX, u_hi = -FLT_MAX, v_lo = FLT_MAX, v_hi = -FLT_MAX;
  float z_lo = FLT_MAX, z_hi = -FLT_MAX;
  bool crosses_camera_plane = false;
  for (int c = 0; c < 8; ++c) {
    const Vec3f corner{origin.x + ((c & 1) ? side_m : 0.0f),
                       origin.y + (((c >> 1) & 1) ? side_m : 0.0f),
                       origin.z + ((c >> 2) ? side_m : 0.0f)};
    const Vec3f p = T_cw * corner;
    z_lo = p.z < z_lo ? p.z : z_lo;
    z_hi = p.z > z_hi ? p.z : z_hi;
    if (p.z <= 1e-4f) {
      crosses_camera_plane = true;
      continue;
    }
    const Vec2f uv = cam.project(p);
    u_lo = uv.x < u_lo ? uv.x : u_lo;
    u_hi = uv.x > u_hi ? uv.x : u_hi;
    v_lo = uv.y < v_lo ? uv.y : v_lo;
    v_hi = uv.y > v_hi ? uv.y : v_hi;
  }
  if (z_hi < min_depth_m || z_lo > max_depth_m) return false;
  if (crosses_camera_plane) {  // the box surrounds the camera plane: it may cover any pixel
    u_lo = v_lo = 0.0f;
    u_hi = static_cast<float>(cam.width);
    v_hi = static_cast<float>(cam.height);
  }
  if (u_hi < -0.5f || v_hi < -0.5f || u_lo > static_cast<float>(cam.width) - 0.5f ||
      v_lo > static_cast<float>(cam.height) - 0.5f)
    return false;
  const float inv_tile = 1.0f / static_cast<float>(tiles.tile_px);
  auto tile_index = [inv_tile](float px, int count) {
    const int t = static_cast<int>(floorf((px + 0.5f) * inv_tile));
    return t < 0 ? 0 : (t >= count ? count - 1 : t);
  };
  rect->tx0 = tile_index(u_lo, tiles.tiles_x);
  rect->tx1 = tile_index(u_hi, tiles.tiles_x);
  rect->ty0 = tile_index(v_lo, tiles.tiles_y);
  rect->ty1 = tile_index(v_hi, tiles.tiles_y);
  rect->z_lo = z_lo > min_depth_m ? z_lo : min_depth_m;
  rect->z_hi = z_hi < max_depth_m ? z_hi : max_depth_m;
  return true;
}

/// Projects one block's bounding box into the range tiles (atomic min/max of depth per tile).
/// Returns false when the block is outside the view or the depth range.
HIVOX_HD inline bool project_block_to_tiles(const Rigid3f& T_cw, const PinholeCamera& cam,
                                            const Vec3i& pos, float block_m, float min_depth_m,
                                            float max_depth_m, const RangeTiles& tiles) {
  TileRect r;
  if (!box_tile_rect(T_cw, cam, to_float(pos) * block_m, block_m, min_depth_m, max_depth_m, tiles,
                     &r))
    return false;
  for (int ty = r.ty0; ty <= r.ty1; ++ty)
    for (int tx = r.tx0; tx <= r.tx1; ++tx) {
      const int t = ty * tiles.tiles_x + tx;
      atomic_min_positive(&tiles.z_min[t], r.z_lo);
      atomic_max_positive(&tiles.z_max[t], r.z_hi);
    }
  return true;
}

}  // namespace hivox::kernels

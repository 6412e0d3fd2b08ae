#include "raycast/cpu/packet_search.h"

namespace hivox::cpu {

void search_hints(const MapView& map, kernels::BlockLookupCache& cache, PacketScratch& s,
                  const Vec3f& o, int n, const kernels::RayMarchConstants& k, float z_max) {
  using namespace kernels;
  const int min_w = k.min_weight;
  // The sample at the hint starts the search, and usually ends it: its cell holds the crossing.
  for (int i = 0; i < n; ++i) {
    s.found[i] = false;
    s.points[i] = o + s.rays[i].dir * s.rays[i].hints.hint;
    s.dirs[i] = s.rays[i].dir;
    s.inv_dirs[i] = s.rays[i].inv_dir;
  }
  sample_tsdf_packet(map, cache, s.lookups, n, s.points, s.dirs, s.inv_dirs, min_w, s.cells,
                     s.samples, s.levels, s.sampled);
  int live = 0;
  int bracketed[kPacketRays];
  int n_bracketed = 0;
  for (int i = 0; i < n; ++i) {
    if (!s.sampled[i]) continue;
    const PacketRay& ray = s.rays[i];
    if (s.samples[i].at_crossing()) {
      exact_bracket(map, ray.dir, ray.hints.hint, s.samples[i], s.levels[i], &s.bracket[i]);
      bracketed[n_bracketed++] = i;
    } else if (hint_search_begin(map, ray.dir, ray.hints.hint, s.samples[i], s.levels[i], k,
                                 &s.search[i])) {
      s.live[live++] = i;
    }
  }
  // Samples the live rays s.live[0, live) at the ray parameters `next(ray)` gives.
  auto sample_live = [&](int live_rays, auto&& next) {
    for (int j = 0; j < live_rays; ++j) {
      const int i = s.live[j];
      s.z[j] = next(i);
      s.points[j] = o + s.rays[i].dir * s.z[j];
      s.dirs[j] = s.rays[i].dir;
      s.inv_dirs[j] = s.rays[i].inv_dir;
    }
    sample_tsdf_packet(map, cache, s.lookups, live_rays, s.points, s.dirs, s.inv_dirs, min_w,
                       s.cells, s.samples, s.levels, s.sampled);
  };
  // Newton steps until the crossing is bracketed (or the ray gives up).
  while (live > 0) {
    sample_live(live, [&](int i) { return hint_search_next(s.search[i], k); });
    int kept = 0;
    for (int j = 0; j < live; ++j) {
      const int i = s.live[j];
      const HintStep step =
          hint_search_update(s.search[i], map, s.rays[i].dir, s.z[j], s.sampled[j], s.samples[j],
                             s.levels[j], &s.bracket[i]);
      if (step == HintStep::Bracketed) bracketed[n_bracketed++] = i;
      if (step == HintStep::Continue) s.live[kept++] = i;
    }
    live = kept;
  }
  // Secant steps until each bracket is short or exact.
  live = 0;
  for (int j = 0; j < n_bracketed; ++j)
    if (!s.bracket[bracketed[j]].exact) s.live[live++] = bracketed[j];
  while (live > 0) {
    sample_live(live, [&](int i) { return bracket_secant(s.bracket[i]); });
    int kept = 0;
    for (int j = 0; j < live; ++j) {
      const int i = s.live[j];
      if (!bracket_update(s.bracket[i], s.z[j], s.sampled[j], s.samples[j], s.levels[j]))
        s.live[kept++] = i;
    }
    live = kept;
  }
  // The hits within range, and their normals.
  int with_hit = 0;
  for (int j = 0; j < n_bracketed; ++j) {
    const int i = bracketed[j];
    bracket_hit(s.bracket[i], o, s.rays[i].dir, &s.hits[i]);
    if (s.hits[i].depth_m > z_max) continue;
    // The hit's colour is read when the packet is written out: fetch it while the normals are
    // computed (an uncached read per hit otherwise).
    if (map.color != nullptr && s.hits[i].color_ptr >= 0)
      __builtin_prefetch(&map.color[static_cast<int64_t>(s.hits[i].color_ptr) * kBlockVoxels +
                                    s.hits[i].color_index]);
    s.live[with_hit] = i;
    s.points[with_hit] = s.hits[i].p_w;
    s.levels[with_hit] = s.hits[i].level;
    ++with_hit;
  }
  samples_one_voxel_ahead_packet(map, cache, s.lookups, with_hit, s.points, s.levels, min_w,
                                 s.normal_cells, s.ahead, s.sampled);
  for (int j = 0; j < with_hit; ++j) {
    const int i = s.live[j];
    RayHit& hit = s.hits[i];
    // As tsdf_normal: the forward differences, else the gradient at the hit.
    hit.normal_w =
        s.sampled[j] ? normal_from_ahead(s.ahead[j], 0.0f) : normalized(s.bracket[i].best.gradient);
    s.found[i] = true;
  }
}

}  // namespace hivox::cpu

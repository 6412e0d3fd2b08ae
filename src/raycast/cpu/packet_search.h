#pragma once
// The CPU's ray packets: the hinted rays of a range tile searched together, their samples
// addressed and interpolated in vectorized loops (cpu/ray_packets.h). The per-ray search
// (kernels::search_at_hints) is the reference they are tested against.

#include "hivox/map/map_view.h"
#include "raycast/cpu/ray_packets.h"
#include "raycast/raycast_kernels.h"

namespace hivox::cpu {

constexpr int kPacketRays = 64;

struct PacketRay {
  int x = 0, y = 0;
  Vec3f dir;
  Vec3f inv_dir;  ///< kernels::inverse_direction(dir)
  kernels::RayHints hints;
  bool at_second = false;  ///< searched again at `hints.second` after the search at `hints.hint`
};

/// One thread's packet: its rays, their search state and outcomes, and the cells it samples.
struct PacketScratch {
  PacketRay rays[kPacketRays];
  kernels::RayHit hits[kPacketRays];
  bool found[kPacketRays];
  kernels::HintSearch search[kPacketRays];
  kernels::CrossingBracket bracket[kPacketRays];
  // Per sample of a step (indexed by the step's list of live rays).
  int live[kPacketRays];
  float z[kPacketRays];
  Vec3f points[kPacketRays];
  Vec3f dirs[kPacketRays];
  Vec3f inv_dirs[kPacketRays];
  kernels::TsdfSample samples[kPacketRays];
  int levels[kPacketRays];
  bool sampled[kPacketRays];
  Vec3f ahead[kPacketRays];
  kernels::PacketLookups lookups;
  kernels::CellBatch<kPacketRays> cells;
  kernels::CellBatch<3 * kPacketRays> normal_cells;
};

/// `hit_near_hint` for the `n` rays of a packet, step by step: `found[i]` when ray i's surface
/// was found near its hint within `z_max` (`hits[i]` filled); the others march.
void search_hints(const MapView& map, kernels::BlockLookupCache& cache, PacketScratch& s,
                  const Vec3f& o, int n, const kernels::RayMarchConstants& k, float z_max);

}  // namespace hivox::cpu

#pragma once
// The mesh renderer's two ways of casting its rays, private to the module and its tests:
// `render()` uses packets; the ray-by-ray path stays as the reference the packets are tested
// against (they must give the same frames).

#include "hivox/synth_mesh/mesh_render.h"

namespace hivox {

enum class MeshRayMode {
  Single,   ///< one rtcIntersect1 per pixel
  Packets,  ///< rtcIntersect16 per 4 x 4 pixel tile (what `render` uses)
};

RenderedFrame render_mesh(const MeshScene& scene, const PinholeCamera& camera, const Pose& T_wc,
                          double max_depth_m, MeshRayMode mode);

}  // namespace hivox

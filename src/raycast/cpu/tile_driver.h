#pragma once
// The CPU's raycast driver: the image in range tiles, handed out to the CPU's threads, each with
// its own block look-up cache and ray packet. Within a tile, hinted rays are searched together in
// packets (cpu/packet_search.h) and the others ray by ray (kernels::search_at_hints); rays whose
// hints fail march over their tile's range, or only over the stretch that crosses the tile's
// surface boxes when there are any. A GPU driver runs kernels::cast_ray per pixel instead.

#include <cstdint>

#include "hivox/core/camera.h"
#include "hivox/core/image.h"
#include "hivox/core/math.h"
#include "hivox/map/map_view.h"
#include "raycast/raycast_kernels.h"
#include "raycast/surface_tiles.h"

namespace hivox::cpu {

/// Everything one raycast's tiles read: the map, the camera and its pose, the hints, the range
/// tiles (filled), the march's constants and where to write.
struct TileRaycast {
  MapView map;
  PinholeCamera camera;
  Rigid3f T_wc;
  const DepthImage* start_hint_m = nullptr;
  const DepthImage* fallback_hint_m = nullptr;
  kernels::RangeTiles tiles;
  kernels::RayMarchConstants k;
  kernels::SurfaceTiles surface;  ///< empty: rays march their tile's whole range
  bool packets = false;           ///< search hinted rays in packets
  kernels::RaycastOutputView out;
};

/// How the rays of a raycast ended.
struct RayCounts {
  int64_t hits = 0;
  int64_t found_at_hint = 0;      ///< found near a hint, without a march
  int64_t found_at_fallback = 0;  ///< of those, near the fallback hint
};

/// Casts every pixel's ray, tile by tile on the CPU's threads.
RayCounts cast_tiles(const TileRaycast& cast);

}  // namespace hivox::cpu

#pragma once
/// @file
/// Voxel storage. Every level stores 8x8x8-voxel blocks; voxel `i` of block `b` at level `l`
/// sits at world position `(8 b + i) * s_l` (voxel samples on block corners, so the 8 children of
/// a level-l block subdivide it exactly and even child voxels coincide with parent voxels).
///
/// Data are split by field so that integration without colour touches 4 bytes per voxel:
/// `TsdfVoxel` (4 B) always, `ColorVoxel` (4 B) when colour is stored.

#include <cmath>
#include <cstdint>

#include "hivox/core/hd.h"
#include "hivox/core/math.h"

namespace hivox {

inline constexpr int kBlockSide = 8;
inline constexpr int kBlockVoxels = kBlockSide * kBlockSide * kBlockSide;
inline constexpr float kTsdfScale = 32767.0f;  ///< int16 units per unit of normalised TSDF

/// Normalised TSDF F in [-1, 1] (signed distance / truncation, positive in front of the surface)
/// as int16, and the integration weight (number of observations, capped).
struct TsdfVoxel {
  int16_t tsdf = static_cast<int16_t>(kTsdfScale);
  uint16_t weight = 0;
};
static_assert(sizeof(TsdfVoxel) == 4);

/// Colour (sRGB, 8 bit per channel) and its own weight: colour is fused only near the surface.
struct ColorVoxel {
  uint8_t r = 0, g = 0, b = 0;
  uint8_t weight = 0;
};
static_assert(sizeof(ColorVoxel) == 4);

HIVOX_HD inline float tsdf_to_float(int16_t v) {
  return static_cast<float>(v) * (1.0f / kTsdfScale);
}
HIVOX_HD inline int16_t tsdf_from_float(float f) {
  f = f > 1.0f ? 1.0f : (f < -1.0f ? -1.0f : f);
  return static_cast<int16_t>(floorf(f * kTsdfScale + 0.5f));
}

/// A TsdfVoxel read as one 32-bit word (int16 TSDF low, uint16 weight high), as the vectorized
/// kernels read it: its TSDF sign-extended in 32 bits (a 16-bit type in a loop would hold the
/// loop to narrower vectors).
HIVOX_HD inline int32_t tsdf_of_word(uint32_t word) {
  return static_cast<int32_t>(word << 16) >> 16;
}

/// Linear index of voxel (x, y, z) inside a block; x runs fastest.
HIVOX_HD inline int voxel_index(int x, int y, int z) {
  return x + kBlockSide * (y + kBlockSide * z);
}
HIVOX_HD inline Vec3i voxel_coords(int index) {
  return {index % kBlockSide, (index / kBlockSide) % kBlockSide, index / (kBlockSide * kBlockSide)};
}

}  // namespace hivox

#pragma once
/// @file
/// Map parameters: what shapes the voxels (resolution levels, truncation band, colour) and the
/// capacities, which are runtime settings.

#include <cstdint>
#include <string>

namespace hivox {

/// Upper bound of `MapParams::levels` (plain arrays in kernel views are sized by it).
inline constexpr int kMaxLevels = 4;
/// Upper bound of the truncation band in voxels of the finest level (allocation's work per pixel
/// grows with it).
inline constexpr int kMaxTruncationVoxels = 512;

struct MapParams {
  float voxel_size_m = 0.002f;  ///< finest voxel size s; level l has s * 2^l
  int levels = 3;               ///< number of resolution levels, 1 (fixed grid) to kMaxLevels
  /// Truncation band mu, one metric value for all levels: voxels store the signed distance over
  /// mu, so everything that reads distances from the map (raycasting, refinement, evaluation)
  /// takes it from here, and fusion writes with it.
  float truncation_m = 0.024f;
  int64_t max_blocks = 1 << 20;  ///< voxel-block pool size shared by all levels (--max-blocks)
  int64_t buckets_per_level = 1 << 20;  ///< hash buckets per level (power of two)
  int64_t excess_per_level = 1 << 20;   ///< overflow (chain) entries per level
  bool store_color = true;              ///< keep a 4-byte colour per voxel

  float voxel_size_at(int level) const { return voxel_size_m * static_cast<float>(1 << level); }
  float block_size_at(int level) const { return 8.0f * voxel_size_at(level); }
  int bytes_per_voxel() const { return store_color ? 8 : 4; }

  /// Whether `other` shapes voxels differently (voxel size, levels, truncation, colour; the
  /// capacities do not count): the first such field in words, naming both values, or empty.
  std::string shape_difference(const MapParams& other) const;

  /// Throws `Error(InvalidArgument)` naming the bad field.
  void validate() const;
  /// Warns (log) about combinations that work badly, e.g. a truncation band narrower than two
  /// voxels of the coarsest level (holes in coarse surfaces).
  void warn_about_combinations() const;
  std::string to_string() const;
};

}  // namespace hivox

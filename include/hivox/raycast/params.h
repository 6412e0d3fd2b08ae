#pragma once
/// @file
/// Raycasting parameters.

#include <string>

namespace hivox {

/// When a raycast lists the surface boxes of each range tile (RaycastParams::surface_tiles).
enum class SurfaceTileUse { Never, WithoutHints, Always };

/// Switches of the CPU raycaster that trade memory and set-up for speed. Every setting finds the
/// same surfaces (tests pin each against the plain path: hits agree to the crossing's
/// refinement tolerance, most bit for bit); users never need to touch them.
struct RaycastTuning {
  static constexpr int kMaxRangeTilePx = 64;
  int range_tile_px = 8;  ///< side of the tiles of the min/max depth range image, 1 to 64
  /// The CPU driver searches the hinted rays of a tile together, interpolating their samples in
  /// vectorized loops; false: ray by ray (the reference the packets are tested against).
  bool ray_packets = true;
  /// Marches cross cubes of 4x4x4 blocks of the coarsest level that hold no block in one step
  /// (a grid rebuilt per raycast); false: block by block.
  bool coarse_skipping = true;
  /// Marching rays (those without a hint, or whose hint search failed) first test the boxes
  /// around the blocks with a surface that project into their range tile, and march only from
  /// the first box they enter to the last they leave; a ray that enters none has no surface
  /// (no march). The lists are rebuilt per raycast, which pays where most rays march: by
  /// default only in raycasts without hints (renders from free viewpoints). With hints most rays
  /// find their surface without a march (measured: the tracked pipeline's 320x240 raycast ~4 %
  /// slower with the lists, the 640x480 one unchanged within noise).
  SurfaceTileUse surface_tiles = SurfaceTileUse::WithoutHints;

  void validate() const;
};

/// How rays find the surface. The truncation band comes from the map (MapParams::truncation_m)
/// and the depth range from each call (Raycaster::raycast).
struct RaycastParams {
  /// Fraction of the TSDF distance taken as the step inside the truncation band (< 1 because
  /// the projective TSDF overestimates distances seen at an angle).
  float step_fraction = 0.8f;
  int min_weight = 1;  ///< voxels observed fewer times count as unknown
  /// With a start hint, rays begin this many truncation bands in front of the hinted depth.
  float hint_margin_mu = 2.0f;
  /// Where a pixel's two hints (see Raycaster::raycast) lie within this many truncation bands of
  /// each other, they point at one surface and the fallback is searched first: a previous
  /// raycast says where the model holds that surface, without the sensor's noise, so the search
  /// usually ends in the first cell it samples. 0: the start hint first everywhere.
  float hint_agreement_mu = 1.0f;
  RaycastTuning tuning;

  void validate() const;
  std::string to_string() const;
};

}  // namespace hivox

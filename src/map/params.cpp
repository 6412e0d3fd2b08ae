#include "hivox/map/params.h"

#include <cmath>

#include <fmt/format.h>

#include "hivox/core/error.h"
#include "hivox/core/log.h"

namespace hivox {

namespace {
bool is_power_of_two(int64_t v) {
  return v > 0 && (v & (v - 1)) == 0;
}
}  // namespace

void MapParams::validate() const {
  if (!std::isfinite(voxel_size_m) || voxel_size_m <= 0.0f || voxel_size_m > 1.0f)
    fail(ErrorCode::InvalidArgument, "voxel_size_m must be in (0, 1] metres, got {}", voxel_size_m);
  if (!std::isfinite(truncation_m) || truncation_m <= 0.0f || truncation_m > 1.0f)
    fail(ErrorCode::InvalidArgument, "truncation_m must be in (0, 1] metres, got {}", truncation_m);
  // Allocation walks each pixel's band [d - mu, d + mu] block by block: a band of thousands of
  // blocks is a configuration error (a voxel size in the wrong unit), not a workload.
  if (std::isfinite(voxel_size_m) && voxel_size_m > 0.0f &&
      truncation_m > kMaxTruncationVoxels * voxel_size_m)
    fail(ErrorCode::InvalidArgument,
         "truncation_m {} m is {:.0f} voxels of {} m; at most {} are allowed: raise voxel_size_m "
         "or lower truncation_m",
         truncation_m, truncation_m / voxel_size_m, voxel_size_m, kMaxTruncationVoxels);
  if (levels < 1 || levels > kMaxLevels)
    fail(ErrorCode::InvalidArgument, "levels must be between 1 and {}, got {}", kMaxLevels, levels);
  if (max_blocks < 1 || max_blocks > (int64_t{1} << 30))
    fail(ErrorCode::InvalidArgument, "max_blocks must be in [1, 2^30], got {}", max_blocks);
  if (!is_power_of_two(buckets_per_level) || buckets_per_level > (int64_t{1} << 28))
    fail(ErrorCode::InvalidArgument,
         "buckets_per_level must be a power of two no larger than 2^28, got {}", buckets_per_level);
  if (excess_per_level < 0 || excess_per_level > (int64_t{1} << 28))
    fail(ErrorCode::InvalidArgument, "excess_per_level must be in [0, 2^28], got {}",
         excess_per_level);
}

void MapParams::warn_about_combinations() const {
  const float finest = voxel_size_m;
  const float coarsest = voxel_size_at(levels - 1);
  if (truncation_m < finest)
    log::warn("truncation_m {:.4f} m is below the voxel size {:.4f} m: surfaces will have holes",
              truncation_m, finest);
  else if (truncation_m < 2.0f * coarsest)
    log::warn(
        "truncation_m {:.4f} m is less than 2x the coarsest voxel size ({:.4f} m): the coarsest "
        "level sees a band of about one voxel and meshes may have holes; use >= {:.4f} m",
        truncation_m, coarsest, 2.0f * coarsest);
}

std::string MapParams::to_string() const {
  std::string sizes;
  for (int l = 0; l < levels; ++l)
    sizes += fmt::format("{}{:.1f}", l ? "/" : "", voxel_size_at(l) * 1000.0f);
  return fmt::format(
      "voxel {} mm ({} level{}), truncation {:.1f} mm, max_blocks {}, buckets/level {}, "
      "excess/level {}, colour {}",
      sizes, levels, levels > 1 ? "s" : "", truncation_m * 1000.0f, max_blocks, buckets_per_level,
      excess_per_level, store_color ? "on" : "off");
}

std::string MapParams::shape_difference(const MapParams& other) const {
  // Exact comparisons: a map's voxels sit at multiples of its voxel size, so any difference
  // moves them.
  if (voxel_size_m != other.voxel_size_m)
    return fmt::format("voxel size {:g} m against {:g} m", voxel_size_m, other.voxel_size_m);
  if (levels != other.levels) return fmt::format("{} levels against {}", levels, other.levels);
  if (truncation_m != other.truncation_m)
    return fmt::format("truncation {:g} m against {:g} m", truncation_m, other.truncation_m);
  if (store_color != other.store_color)
    return fmt::format("colour {} against {}", store_color ? "stored" : "not stored",
                       other.store_color ? "stored" : "not stored");
  return {};
}

}  // namespace hivox

#pragma once
/// @file
/// A map's content in a canonical order, independent of where its blocks sit in the pool or the
/// hash tables (which depend on the order of insertion), and a map rebuilt from such content:
/// what map files store and load.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "hivox/core/camera.h"
#include "hivox/core/pose.h"
#include "hivox/map/voxel_block_map.h"

namespace hivox {

/// Where the reconstruction that filled a map stood when the map was stored: what continuing it
/// needs besides the voxels (map files keep it with the map).
struct MapSession {
  int64_t frames_fused = 0;       ///< frames integrated into the map (the refinement's cadence)
  std::optional<Pose> last_pose;  ///< T_wc of the last frame: where tracking resumes
  std::optional<PinholeCamera> camera;  ///< the depth camera that saw the frames
};

/// Largest magnitude of a stored block coordinate: voxel coordinates of every level (8 b + 7,
/// and twice that one level finer) stay far inside int32.
inline constexpr int32_t kMaxStoredBlockCoord = 1 << 24;

/// The allocated blocks of `level`, sorted by (z, y, x).
std::vector<BlockRef> sorted_blocks(const VoxelBlockMap& map, int level);
/// The Split entries of `level` (regions that live one level finer), sorted by (z, y, x).
std::vector<Vec3i> sorted_split_entries(const VoxelBlockMap& map, int level);

/// Writes the content of restored block `i`: its 512 voxels, its colours (null when the map
/// stores none; both cleared to "unobserved" beforehand) and its count of fused frames since its
/// content was created (BlockMeta::updates).
using FillStoredBlock =
    std::function<void(std::size_t i, TsdfVoxel* tsdf, ColorVoxel* color, uint16_t* updates)>;

/// Rebuilds the content of the empty `map`: allocates `blocks`, has `fill` write each one's
/// content (called once per block, in parallel), computes their surface summaries, and marks
/// `splits` as Split entries. Before touching the map it checks that the content is a valid
/// hierarchy: levels in range, coordinates within +-kMaxStoredBlockCoord, no key twice, Split
/// entries only above the finest level and each with its 8 children one level finer, no region
/// at two levels. A violation is `Error(InvalidData)` naming `what` (e.g. the file) and the first
/// bad key; a map that is not empty is `Error(InvalidArgument)`; blocks beyond the map's
/// capacities are `Error(OutOfCapacity)` naming the option to raise. On error the map is left
/// empty.
void restore_blocks(VoxelBlockMap& map, std::span<const BlockKey> blocks,
                    std::span<const BlockKey> splits, const FillStoredBlock& fill,
                    std::string_view what);

}  // namespace hivox

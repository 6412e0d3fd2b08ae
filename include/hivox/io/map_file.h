#pragma once
/// @file
/// Map files (`.hvx`): a map with every level, the settings that shaped its voxels and where the
/// run that filled it stood, so that it can be loaded, continued, meshed, rendered or exported
/// later. docs/map-files.md describes the layout and why it is this one.
///
/// A file is written whole or not at all (AtomicFile). Reading checks, before building anything:
/// the magic, the format version (a newer one is `Error(Unsupported)`), the end marker (a
/// truncated file), the checksum over every byte before it (any changed byte), then every count,
/// size and block of the content; each failure is one `Error` naming the file and the problem,
/// and no half-loaded map is ever returned.

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "hivox/fusion/params.h"
#include "hivox/map/params.h"
#include "hivox/map/stored_map.h"
#include "hivox/map/voxel_block_map.h"

namespace hivox {

/// The format version this build writes and the newest it reads.
inline constexpr uint32_t kMapFileVersion = 1;

/// What a map file holds besides its voxels.
struct MapFileInfo {
  uint32_t format_version = 0;
  std::string library_version;  ///< of the hivox that wrote it
  /// The map's shape (voxel size, levels, truncation, colour); the capacities are MapParams'
  /// defaults (a file holds content, not the capacities of the map that wrote it).
  MapParams map;
  FusionParams fusion;  ///< the fusion settings its frames were integrated with
  MapSession session;
  std::vector<int64_t> blocks_per_level;  ///< allocated blocks, finest level first
  std::vector<int64_t> splits_per_level;  ///< Split entries (regions held one level finer)
  int64_t file_bytes = 0;
};

/// Writes `map` (every level's blocks: coordinates, voxels, colours, update counts; the Split
/// entries) with the fusion settings and the session. Blocks are stored in a canonical order, so
/// the same map content gives the same bytes whatever its history. An unwritable file is
/// `Error(Io)`.
void write_map_file(const std::filesystem::path& path, const VoxelBlockMap& map,
                    const FusionParams& fusion, const MapSession& session);

/// The file's header (magic, version and every field checked), read from the start of the file
/// alone: cheap for any size of map. The checksum over the whole file is checked when the map is
/// loaded (read_map_file).
MapFileInfo read_map_file_info(const std::filesystem::path& path);

/// Whether the file at `path` starts like a map file (its magic), without reading further.
bool is_map_file(const std::filesystem::path& path);

struct LoadedMap {
  std::unique_ptr<VoxelBlockMap> map;
  MapFileInfo info;
};

/// Loads a map file into a new CPU map. Capacities (pool size, hash buckets and overflow per
/// level) come from `capacities` when given (its shape fields are ignored), else MapParams'
/// defaults raised to hold the file's blocks; a file that does not fit them is
/// `Error(OutOfCapacity)` naming the option to raise.
LoadedMap read_map_file(const std::filesystem::path& path,
                        const std::optional<MapParams>& capacities = std::nullopt);

/// Throws `Error(InvalidArgument)` naming the file and the first setting in which `map` or
/// `fusion` would continue the file's map differently from how it was made (voxel size, levels,
/// truncation, colour, maximum weight).
void check_map_continues(const MapFileInfo& info, const std::filesystem::path& path,
                         const MapParams& map, const FusionParams& fusion);

}  // namespace hivox

#pragma once
/// @file
/// The interactive viewer of results (`hivox view PATH`): a run's output folder (its mesh,
/// trajectory, statistics and renders), a mesh file (PLY, OFF) or a saved map (`.hvx`, meshed on
/// loading), shown in the browser with three.js: orbit, zoom and pan; colour by RGB, level or
/// normal; the camera trajectory; the level legend and the run's statistics.
///
/// The page's data: `/api/info.json` (what is shown, counts, the level sizes and colours, the
/// run's stats.json when there is one, the folder's images), `/api/mesh.bin` (the mesh, binary:
/// see mesh_to_binary), `/api/trajectory.json` (camera positions, world frame) and
/// `/files/NAME` (the run folder's own files).

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "hivox/core/math.h"
#include "hivox/core/pose.h"
#include "hivox/mesh/triangle_mesh.h"
#include "hivox/view/server.h"

namespace hivox {

struct ViewerParams {
  /// Meshes with more triangles are decimated for display (vertex clustering) to at most this.
  int64_t max_triangles = 4'000'000;
  float min_weight = 1.0f;  ///< meshing a map file: MeshParams::min_weight

  /// Throws `Error(InvalidArgument)` naming the bad setting.
  void validate() const;
};

/// What the viewer shows, loaded once.
struct ViewerContent {
  enum class Kind { RunFolder, MeshFile, MapFile };
  Kind kind = Kind::MeshFile;
  std::filesystem::path path;
  TriangleMesh mesh;  ///< as displayed (decimated when it had more than max_triangles)
  int64_t source_vertices = 0, source_triangles = 0;  ///< before decimation
  std::vector<Pose> trajectory;                       ///< camera-to-world poses, when known
  std::string stats_json;                             ///< the run's stats.json, or empty
  int levels = 0;                                     ///< 0 when unknown (a mesh without a run)
  float voxel_size_m = 0;                             ///< finest level's, 0 when unknown
  std::filesystem::path folder;     ///< a run folder whose files are served, or empty
  std::vector<std::string> images;  ///< the folder's PNG renders
};

/// Loads `path`: a folder with `mesh.ply` (and optionally `trajectory.txt`, `stats.json`,
/// renders), a `.ply`/`.off` mesh or a `.hvx` map. Throws `Error` naming the path and the
/// problem (missing, unreadable, not one of these).
ViewerContent load_viewer_content(const std::filesystem::path& path, const ViewerParams& params);

/// Registers the viewer's page and data on `server` (before it starts).
void serve_viewer(ViewServer& server, std::shared_ptr<const ViewerContent> content);

/// The mesh as the page reads it, little-endian: "HVXMESH1", then uint32 vertex count, triangle
/// count and flags (1 normals, 2 colours, 4 levels), uint32 0; float32 xyz per vertex; float32
/// normals (flag 1); uint8 RGB per vertex (flag 2); uint8 level per vertex (flag 4); uint32
/// indices, 3 per triangle. Every block starts on a 4-byte boundary (zero padding).
std::string mesh_to_binary(const TriangleMesh& mesh);

/// A mesh of at most `max_triangles` triangles that looks like `mesh` from afar: vertices merged
/// on a grid (attributes averaged, the finest level kept), triangles that collapsed dropped. A
/// mesh within the limit is returned as it is.
TriangleMesh decimate_for_display(const TriangleMesh& mesh, int64_t max_triangles);

}  // namespace hivox

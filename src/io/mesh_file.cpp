#include "hivox/io/mesh_file.h"

#include <algorithm>
#include <cctype>
#include <string>

#include "hivox/core/error.h"
#include "hivox/io/obj.h"
#include "hivox/io/off.h"
#include "hivox/io/ply.h"

namespace hivox {

TriangleMesh read_mesh(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".ply") return read_ply(path);
  if (ext == ".obj") return read_obj(path);
  if (ext == ".off") return read_off(path);
  fail(ErrorCode::Unsupported, "{}: not a mesh file this reads (.ply, .obj, .off)", path.string());
}

}  // namespace hivox

#include "hivox/output/renders.h"

#include "hivox/io/image_io.h"
#include "hivox/raycast/render.h"

namespace hivox {

std::vector<std::filesystem::path> write_renders(const RaycastResult& r,
                                                 const std::filesystem::path& dir,
                                                 const std::string& prefix) {
  const std::vector<std::pair<std::string, ColorImage>> images = {
      {"depth.png", render_depth(r.depth_m)}, {"normals.png", render_normals(r)},
      {"shaded.png", render_shaded(r)},       {"color.png", render_colors(r)},
      {"levels.png", render_levels(r)},
  };
  std::vector<std::filesystem::path> files;
  for (const auto& [name, image] : images) {
    files.push_back(dir / (prefix + name));
    write_png(files.back(), image);
  }
  return files;
}

}  // namespace hivox

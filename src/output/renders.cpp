#include "hivox/output/renders.h"

#include "hivox/io/image_io.h"
#include "hivox/output/legend.h"
#include "hivox/raycast/render.h"

namespace hivox {

std::vector<std::filesystem::path> write_renders(const RaycastResult& r, const MapParams& map,
                                                 const std::filesystem::path& dir,
                                                 const std::string& prefix) {
  const DepthExtent depth = depth_extent(r.depth_m);
  const std::vector<std::pair<std::string, ColorImage>> images = {
      {"depth.png", add_depth_scale(render_depth(r.depth_m, depth.min_m, depth.max_m), depth.min_m,
                                    depth.max_m)},
      {"normals.png", render_normals(r)},
      {"shaded.png", render_shaded(r)},
      {"color.png", render_colors(r)},
      {"levels.png", add_level_legend(render_levels(r), map.levels, map.voxel_size_m)},
  };
  std::vector<std::filesystem::path> files;
  for (const auto& [name, image] : images) {
    files.push_back(dir / (prefix + name));
    write_png(files.back(), image);
  }
  return files;
}

}  // namespace hivox

// Steps in a map's surface where its blocks meet: the map rendered from poses along a trajectory,
// and every pair of neighbouring pixels whose hits lie on one smooth stretch of surface (normals
// within 14 degrees, points at most 6 mm apart) checked for how far apart the two hits lie along
// the normal. Inside a block such pairs differ by noise alone; where the pair crosses a block
// border, more of them step apart where the blocks' voxels were fused from different histories
// (a block allocated, split or merged later than its neighbour follows later frames, and where
// depth and poses drift apart over a sequence their surfaces part), and across a level border also
// where two resolutions disagree. The counts say how often the renders show such steps.
//
//   render_steps out/run/trajectory.txt --every 40 a.hvx b.hvx
//
// Each map is rendered with the camera it was made with (a map that does not say is refused) and
// the raycaster's defaults; the hits' levels tell the blocks apart.

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "hivox/core/error.h"
#include "hivox/io/map_file.h"
#include "hivox/io/trajectory_io.h"
#include "hivox/raycast/raycaster.h"

namespace {

using namespace hivox;

/// Pairs of neighbouring hits on one smooth stretch of surface, and those apart along the normal
/// by more than 1 and 2 mm.
struct Steps {
  int64_t pairs = 0, over_1mm = 0, over_2mm = 0;
  void add(float apart_m) {
    ++pairs;
    over_1mm += apart_m > 0.001f;
    over_2mm += apart_m > 0.002f;
  }
  void print(const char* what) const {
    std::printf("  %-22s %10lld pairs, apart > 1 mm %6.2f %%, > 2 mm %6.2f %%\n", what,
                static_cast<long long>(pairs), pairs > 0 ? 100.0 * over_1mm / pairs : 0.0,
                pairs > 0 ? 100.0 * over_2mm / pairs : 0.0);
  }
};

struct MapSteps {
  int64_t hits = 0;
  Steps inside, same_level, across_levels;
};

MapSteps measure(const std::string& path, const std::vector<Pose>& poses) {
  const LoadedMap m = read_map_file(path);
  if (!m.info.session.camera)
    fail(ErrorCode::InvalidArgument, "{}: the map does not say which camera made it", path);
  const PinholeCamera cam = *m.info.session.camera;
  const MapView view = m.map->view();
  Raycaster raycaster{RaycastParams{}};
  MapSteps out;
  for (const Pose& T_wc : poses) {
    const RaycastResult& r = raycaster.raycast(*m.map, cam, T_wc, DepthRange{0.2f, 3.0f});
    for (int y = 0; y < cam.height; ++y)
      for (int x = 0; x < cam.width; ++x) {
        if (!r.hit(x, y)) continue;
        ++out.hits;
        const Vec3f p = r.points_w(x, y), n = r.normals_w(x, y);
        for (const auto& [u, v] : {std::pair{x + 1, y}, std::pair{x, y + 1}}) {
          if (u >= cam.width || v >= cam.height || !r.hit(u, v)) continue;
          const Vec3f q = r.points_w(u, v), nq = r.normals_w(u, v);
          const Vec3f pq = q - p;
          if (dot(n, nq) < 0.97f || dot(pq, pq) > 0.006f * 0.006f) continue;
          const float apart = std::abs(dot(n, pq));
          const int lp = r.levels(x, y), lq = r.levels(u, v);
          if (lp != lq)
            out.across_levels.add(apart);
          else if (!(block_of_point(view.level[lp], p) == block_of_point(view.level[lq], q)))
            out.same_level.add(apart);
          else
            out.inside.add(apart);
        }
      }
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Steps in a map's surface where its blocks meet, in renders along a trajectory"};
  std::string trajectory;
  int every = 40;
  std::vector<std::string> maps;
  app.add_option("trajectory", trajectory, "TUM trajectory file: the render poses")->required();
  app.add_option("maps", maps, "map files (.hvx)")->required();
  app.add_option("--every", every, "render every N-th pose")->check(CLI::PositiveNumber);
  CLI11_PARSE(app, argc, argv);
  try {
    std::vector<Pose> poses;
    const std::vector<StampedPose> all = read_tum_trajectory(trajectory);
    for (std::size_t i = 0; i < all.size(); i += static_cast<std::size_t>(every))
      poses.push_back(all[i].T_wc);
    for (const std::string& path : maps) {
      const MapSteps s = measure(path, poses);
      std::printf("%s: %zu renders, %lld hits; neighbouring hits on smooth surface\n", path.c_str(),
                  poses.size(), static_cast<long long>(s.hits));
      s.inside.print("inside a block");
      s.same_level.print("across a block border");
      s.across_levels.print("across a level border");
    }
  } catch (const Error& e) {
    std::fprintf(stderr, "render_steps: %s\n", e.what());
    return 1;
  }
  return 0;
}

#include "hivox/raycast/warp.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <vector>

#include "core/parallel.h"
#include "hivox/core/error.h"
#include "hivox/raycast/raycaster.h"
#include "raycast/warp_kernels.h"

namespace hivox {

void warp_raycast_depth(const RaycastResult& from, const PinholeCamera& camera, const Pose& T_wc,
                        float max_gap_m, DepthImage* out, WarpScratch* scratch) {
  camera.validate("warp camera");
  if (!(max_gap_m > 0.0f))
    fail(ErrorCode::InvalidArgument, "warp max_gap_m {} must be > 0", max_gap_m);
  const int w = camera.width, h = camera.height;
  WarpScratch local;
  WarpScratch& s = scratch != nullptr ? *scratch : local;
  // The nearest depth landing on each pixel (FLT_MAX: none yet). Each thread keeps its own
  // (the first thread's is `nearest`), merged row by row afterwards: an atomic minimum per hit
  // cost most of the warp.
  DepthImage& nearest = s.nearest;
  // camera.project and camera.ray are written out in warp_landing on these copies: called on the
  // camera object, they keep GCC from vectorizing the loop (its fields stay loads through memory).
  const kernels::WarpView view =
      kernels::WarpView::of(to_rigid3f(T_wc.inverse()), camera, max_gap_m);
  const int from_w = from.depth_m.width(), from_h = from.depth_m.height();
  int threads = 1;
  parallel_team([&](const ThreadTeam& team) {
    team.single([&] {
      threads = team.size();
      if (static_cast<int>(s.partial.size()) < threads - 1) s.partial.resize(threads - 1);
    });
    const int thread = team.index();
    DepthImage& mine = thread == 0 ? nearest : s.partial[thread - 1];
    mine.resize(w, h, FLT_MAX);
    // Row by row: where each hit lands and at which depth, in a loop without branches or
    // conversions (it vectorizes), then the landings into `mine`.
    std::vector<float> landing_u(static_cast<std::size_t>(from_w));
    std::vector<float> landing_v(static_cast<std::size_t>(from_w));
    std::vector<float> landing_z(static_cast<std::size_t>(from_w));  // 0: lands nowhere
    const ThreadTeam::Share rows = team.static_share(from_h);
    for (int y = static_cast<int>(rows.begin); y < static_cast<int>(rows.end); ++y) {
      const float* depth = &from.depth_m(0, y);
      const Vec3f* points = &from.points_w(0, y);
      const Vec3f* normals = &from.normals_w(0, y);
#pragma omp simd
      for (int x = 0; x < from_w; ++x)
        landing_z[x] = kernels::warp_landing(view, depth[x], points[x], normals[x], &landing_u[x],
                                             &landing_v[x]);
      float* m = mine.data();
      for (int x = 0; x < from_w; ++x) {
        if (!(landing_z[x] > 0.0f)) continue;
        const int64_t i = static_cast<int64_t>(landing_v[x]) * w + static_cast<int>(landing_u[x]);
        m[i] = std::min(m[i], landing_z[x]);
      }
    }
  });
  // The threads' landings merged, and the nearest depth landed within one pixel: a minimum over
  // each row's 3 pixels, then over 3 rows (loops without branches, which vectorize).
  DepthImage& row_min = s.row_min;  // every pixel written below
  if (row_min.width() != w || row_min.height() != h) row_min.resize(w, h);
  parallel_for(h, [&](int64_t row) {
    const int y = static_cast<int>(row);
    float* n = &nearest(0, y);
    for (int t = 0; t + 1 < threads; ++t) {
      const float* other = &s.partial[t](0, y);
      for (int x = 0; x < w; ++x) n[x] = std::min(n[x], other[x]);
    }
    float* r = &row_min(0, y);
    for (int x = 1; x + 1 < w; ++x) r[x] = std::min(n[x - 1], std::min(n[x], n[x + 1]));
    r[0] = std::min(n[0], w > 1 ? n[1] : FLT_MAX);
    if (w > 1) r[w - 1] = std::min(n[w - 2], n[w - 1]);
  });
  if (out->width() != w || out->height() != h) out->resize(w, h);  // every pixel written below
  auto landed = [&](int u, int v) {
    return u >= 0 && v >= 0 && u < w && v < h ? nearest(u, v) : FLT_MAX;
  };
  const std::vector<float> no_row(static_cast<std::size_t>(w), FLT_MAX);
  parallel_for(h, [&](int64_t image_row) {
    const int y = static_cast<int>(image_row);
    const float* n = &nearest(0, y);
    const float* above = y > 0 ? &row_min(0, y - 1) : no_row.data();
    const float* row = &row_min(0, y);
    const float* below = y + 1 < h ? &row_min(0, y + 1) : no_row.data();
    float* o = &(*out)(0, y);
    auto front = [&](int x) { return std::min(above[x], std::min(row[x], below[x])); };
    for (int x = 0; x < w; ++x) o[x] = kernels::warp_keep(n[x], front(x), max_gap_m);
    for (int x = 0; x < w; ++x)
      if (!(n[x] < FLT_MAX))
        o[x] = kernels::warp_keep(kernels::warp_hole(landed, x, y, max_gap_m), front(x), max_gap_m);
  });
}

}  // namespace hivox

#include "hivox/track/preprocess.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "core/parallel.h"
#include "track_kernels.h"

namespace hivox {

namespace {
/// The nearest depth `range` lets through: zero means invalid whatever the range says.
float nearest_valid_m(const DepthRange& range) {
  return std::max(range.min_m, std::numeric_limits<float>::min());
}
}  // namespace

void bilateral_filter(const DepthImage& in, DepthImage& out, const TrackParams& params,
                      const DepthRange& range) {
  out.resize(in.width(), in.height());
  const ImageView<const float> src = in.view();
  const int r = params.bilateral_radius_px;
  const float inv_px = 1.0f / (2.0f * params.bilateral_sigma_px * params.bilateral_sigma_px);
  const float inv_d =
      1.0f / (2.0f * params.bilateral_sigma_depth_m * params.bilateral_sigma_depth_m);
  const int w = in.width(), h = in.height();
  // Row by row, one neighbour offset at a time over the whole row: the same sums as
  // kernels::bilateral_depth per pixel, in loops over contiguous pixels that vectorize.
  parallel_team([&](const ThreadTeam& team) {
    const int thread = team.index(), threads = team.size();
    std::vector<float> sum(static_cast<std::size_t>(w)), wsum(static_cast<std::size_t>(w));
    for (int y = thread; y < h; y += threads) {
      std::fill(sum.begin(), sum.end(), 0.0f);
      std::fill(wsum.begin(), wsum.end(), 0.0f);
      const float* centre = &src(0, y);
      const float lo = nearest_valid_m(range), hi = range.max_m;
      for (int dy = std::max(-r, -y); dy <= std::min(r, h - 1 - y); ++dy) {
        const float* row = &src(0, y + dy);
        for (int dx = -r; dx <= r; ++dx) {
          const float dist2 = static_cast<float>(dx * dx + dy * dy);
          const int x0 = std::max(0, -dx), x1 = std::min(w, w - dx);
#pragma omp simd
          for (int x = x0; x < x1; ++x) {
            const float d = row[x + dx], d0 = centre[x];
            const float valid = ((d >= lo) & (d <= hi)) ? 1.0f : 0.0f;  // no branch: vectorizes
            const float wt =
                valid * kernels::bilateral_weight(dist2, valid * (d - d0), inv_px, inv_d);
            sum[x] += wt * d;
            wsum[x] += wt;
          }
        }
      }
      float* dst = &out(0, y);
      for (int x = 0; x < w; ++x) {
        const float d0 = centre[x];
        dst[x] = d0 >= lo && d0 <= hi ? sum[x] / wsum[x] : 0.0f;
      }
    }
  });
}

void downsample_depth(const DepthImage& in, DepthImage& out, const TrackParams& params) {
  const int w = in.width() / 2, h = in.height() / 2;
  out.resize(w, h);
  parallel_for(h, [&](int64_t yy) {
    const int y = static_cast<int>(yy);
    for (int x = 0; x < w; ++x) {
      float d[4];
      for (int k = 0; k < 4; ++k) d[k] = in(2 * x + (k & 1), 2 * y + (k >> 1));
      const int mask = kernels::same_surface_2x2(d, params.max_depth_jump_ratio);
      float sum = 0.0f;
      for (int k = 0; k < 4; ++k)
        if (mask & (1 << k)) sum += d[k];
      out(x, y) =
          mask != 0 ? sum / static_cast<float>(std::popcount(static_cast<unsigned>(mask))) : 0.0f;
    }
  });
}

void points_and_normals(const DepthImage& depth_m, const PinholeCamera& camera,
                        const TrackParams& params, Image<Vec3f>& points_c,
                        Image<Vec3f>& normals_c) {
  const int w = depth_m.width(), h = depth_m.height();
  points_c.resize(w, h);
  normals_c.resize(w, h);
  parallel_for(h, [&](int64_t yy) {
    const int y = static_cast<int>(yy);
    for (int x = 0; x < w; ++x) {
      const float d = depth_m(x, y);
      points_c(x, y) = d > 0.0f ? camera.unproject(static_cast<float>(x), static_cast<float>(y), d)
                                : Vec3f{0, 0, 0};
    }
  });
  const ImageView<const Vec3f> p = std::as_const(points_c).view();
  parallel_for(h, [&](int64_t yy) {
    const int y = static_cast<int>(yy);
    for (int x = 0; x < w; ++x)
      normals_c(x, y) = kernels::normal_from_points(p, x, y, params.max_depth_jump_ratio);
  });
}

void build_pyramid(const DepthImage& depth_m, const PinholeCamera& camera,
                   const TrackParams& params, const DepthRange& range,
                   std::vector<PyramidLevel>& levels) {
  levels.resize(static_cast<std::size_t>(params.levels()));
  PyramidLevel& finest = levels[0];
  finest.camera = camera;
  if (params.bilateral_radius_px > 0) {
    bilateral_filter(depth_m, finest.depth_m, params, range);
  } else {
    finest.depth_m = depth_m;
    const float lo = nearest_valid_m(range), hi = range.max_m;
    for (std::size_t i = 0; i < finest.depth_m.size(); ++i) {
      float& d = finest.depth_m.data()[i];
      if (!(d >= lo && d <= hi)) d = 0.0f;
    }
  }
  for (std::size_t l = 0; l < levels.size(); ++l) {
    PyramidLevel& level = levels[l];
    if (l > 0) {
      downsample_depth(levels[l - 1].depth_m, level.depth_m, params);
      level.camera = levels[l - 1].camera.subsampled(2);
    }
    points_and_normals(level.depth_m, level.camera, params, level.points_c, level.normals_c);
  }
}

}  // namespace hivox

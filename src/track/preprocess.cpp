#include "hivox/track/preprocess.h"

#include <cmath>
#include <utility>

#include "hivox/core/parallel.h"
#include "track_kernels.h"

namespace hivox {

void bilateral_filter(const DepthImage& in, DepthImage& out, const TrackParams& params) {
  out.resize(in.width(), in.height());
  const ImageView<const float> src = in.view();
  const int r = params.bilateral_radius_px;
  const float inv_px = 1.0f / (2.0f * params.bilateral_sigma_px * params.bilateral_sigma_px);
  const float inv_d =
      1.0f / (2.0f * params.bilateral_sigma_depth_m * params.bilateral_sigma_depth_m);
  ImageView<float> dst = out.view();
  parallel_for(in.height(), [&](int64_t y) {
    for (int x = 0; x < src.width; ++x)
      dst(x, static_cast<int>(y)) = kernels::bilateral_depth(
          src, x, static_cast<int>(y), r, inv_px, inv_d, params.min_depth_m, params.max_depth_m);
  });
}

void downsample_depth(const DepthImage& in, DepthImage& out, const TrackParams& params) {
  const int w = in.width() / 2, h = in.height() / 2;
  out.resize(w, h);
  parallel_for(h, [&](int64_t yy) {
    const int y = static_cast<int>(yy);
    for (int x = 0; x < w; ++x) {
      float first = 0.0f, sum = 0.0f;
      int n = 0;
      for (int k = 0; k < 4; ++k) {
        const float d = in(2 * x + (k & 1), 2 * y + (k >> 1));
        if (d <= 0.0f) continue;
        if (n == 0) first = d;
        if (!kernels::same_surface(first, d, params.max_depth_jump_ratio)) continue;
        sum += d;
        ++n;
      }
      out(x, y) = n > 0 ? sum / static_cast<float>(n) : 0.0f;
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
                   const TrackParams& params, std::vector<PyramidLevel>& levels) {
  levels.resize(static_cast<std::size_t>(params.levels()));
  PyramidLevel& finest = levels[0];
  finest.camera = camera;
  if (params.bilateral_radius_px > 0) {
    bilateral_filter(depth_m, finest.depth_m, params);
  } else {
    finest.depth_m = depth_m;
    for (std::size_t i = 0; i < finest.depth_m.size(); ++i) {
      float& d = finest.depth_m.data()[i];
      if (!(d >= params.min_depth_m && d <= params.max_depth_m)) d = 0.0f;
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

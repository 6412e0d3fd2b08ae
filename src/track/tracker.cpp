#include "hivox/track/tracker.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <numbers>
#include <vector>

#include "core/parallel.h"
#include "hivox/core/error.h"
#include "hivox/core/timer.h"
#include "track/icp_solver.h"
#include "track_kernels.h"

namespace hivox {

/// One row's sums of a pass (floats: the row's pixels are summed in floats), kept until the rows
/// are summed in order. Two cache lines of its own: rows are written by different threads.
struct alignas(64) Tracker::RowSums {
  float A[21];  ///< upper triangle of J^T W J, row-major
  float b[6];   ///< J^T W r
  float r2 = 0, distance = 0;
  int32_t inliers = 0;
};

/// One thread's buffers for the pass over a row: the weighted Jacobian rows and residuals, and
/// each pixel's world point, model pixel and that pixel's point and normal. Kept across passes.
struct Tracker::RowScratch {
  std::vector<float> rows;  // 7 rows of w: sqrt(weight) * J (6), sqrt(weight) * r
  std::vector<Vec3f> p_w, q_w, m_w;
  std::vector<int32_t> model_pixel;
  std::vector<int32_t> inside;  // (as wide as a float: the loops vectorize)
  void reserve(int w) {
    const auto n = static_cast<std::size_t>(w);
    if (p_w.size() >= n) return;
    rows.resize(7 * n);
    p_w.resize(n);
    q_w.resize(n);
    m_w.resize(n);
    model_pixel.resize(n);
    inside.resize(n);
  }
};

Tracker::Tracker(const TrackParams& params, const DepthRange& depth_range, const Device& device)
    : params_(params), depth_range_(depth_range), device_(device) {
  params_.validate();
  depth_range_.validate("tracking depth range");
  device_.require_available();
}

Tracker::~Tracker() = default;
Tracker::Tracker(Tracker&&) noexcept = default;
Tracker& Tracker::operator=(Tracker&&) noexcept = default;

void Tracker::build_model_pyramid(const RaycastResult& model) {
  model_.resize(static_cast<std::size_t>(params_.levels()));
  ModelLevel& finest = model_[0];
  finest.camera = model.camera;
  finest.points_w = model.points_w;
  finest.normals_w = model.normals_w;  // zero where the ray missed
  finest.depth_m = model.depth_m;
  for (std::size_t l = 1; l < model_.size(); ++l) {
    const ModelLevel& in = model_[l - 1];
    ModelLevel& out = model_[l];
    const int w = in.depth_m.width() / 2, h = in.depth_m.height() / 2;
    out.camera = in.camera.subsampled(2);
    out.points_w.resize(w, h);
    out.normals_w.resize(w, h);
    out.depth_m.resize(w, h);
    parallel_for(h, [&](int64_t yy) {
      const int y = static_cast<int>(yy);
      for (int x = 0; x < w; ++x) {
        // Pixels without a model normal count as empty.
        float dk[4];
        for (int k = 0; k < 4; ++k) {
          const int xs = 2 * x + (k & 1), ys = 2 * y + (k >> 1);
          dk[k] = kernels::is_zero(in.normals_w(xs, ys)) ? 0.0f : in.depth_m(xs, ys);
        }
        const int mask = kernels::same_surface_2x2(dk, params_.max_depth_jump_ratio);
        Vec3f p{0, 0, 0}, n{0, 0, 0};
        float d = 0.0f;
        for (int k = 0; k < 4; ++k) {
          if (!(mask & (1 << k))) continue;
          const int xs = 2 * x + (k & 1), ys = 2 * y + (k >> 1);
          p += in.points_w(xs, ys);
          n += in.normals_w(xs, ys);
          d += dk[k];
        }
        const int count = std::popcount(static_cast<unsigned>(mask));
        out.points_w(x, y) = count > 0 ? p / static_cast<float>(count) : Vec3f{0, 0, 0};
        out.normals_w(x, y) = count > 0 ? normalized(n) : Vec3f{0, 0, 0};
        out.depth_m(x, y) = count > 0 ? d / static_cast<float>(count) : 0.0f;
      }
    });
  }
}

icp::Sums Tracker::reduce(int level, const Pose& T) {
  return dispatch(device_, "the ICP reduction", [&] { return reduce_cpu(level, T); });
}

icp::Sums Tracker::reduce_cpu(int level, const Pose& T) {
  const PyramidLevel& F = frame_[static_cast<std::size_t>(level)];
  const ModelLevel& M = model_[static_cast<std::size_t>(level)];
  const kernels::IcpPass pass(to_rigid3f(T), T_model_cw_, M.camera,
                              params_.max_distance_m * static_cast<float>(1 << level), params_);
  const Vec3f* model_points = M.points_w.data();
  const Vec3f* model_normals = M.normals_w.data();
  const int w = F.depth_m.width(), h = F.depth_m.height();
  const auto threads = static_cast<std::size_t>(thread_count());
  if (scratch_.size() < threads) scratch_.resize(threads);
  row_sums_.resize(static_cast<std::size_t>(h));
  RowSums* const sums = row_sums_.data();
  parallel_team([&](const ThreadTeam& team) {
    const int tid = team.index(), nthreads = team.size();
    if (tid >= static_cast<int>(scratch_.size())) return;
    // Each thread sizes its own buffers: allocated by the thread that writes them, they do not
    // share cache lines with another thread's.
    scratch_[static_cast<std::size_t>(tid)].reserve(w);
    // A copy of the pass's constants: read through the closure, they are loaded again in every
    // iteration (the stores below might alias them), which keeps the loops from vectorizing.
    const kernels::IcpPass c = pass;
    // Per row: the pixels' weighted Jacobian rows and residuals are written first, then summed
    // over the row in floats; rows are summed in doubles.
    RowScratch& scratch = scratch_[static_cast<std::size_t>(tid)];
    float* const Jw = scratch.rows.data();  // 6 columns: sqrt(weight) * J
    float* const rw = Jw + 6 * w;           // sqrt(weight) * r
    Vec3f* const p_w = scratch.p_w.data();
    Vec3f* const q_w = scratch.q_w.data();
    Vec3f* const m_w = scratch.m_w.data();
    int32_t* const model_pixel = scratch.model_pixel.data();
    int32_t* const inside = scratch.inside.data();
    for (int y = tid; y < h; y += nthreads) {
      float row_A[21] = {}, row_b[6] = {}, row_r2 = 0.0f, row_distance = 0.0f;
      int n = 0;
      const Vec3f* points_c = &F.points_c(0, y);
      const Vec3f* normals_c = &F.normals_c(0, y);
      // Three loops: the model pixels (without branches: it vectorizes), their reads (the
      // reads scattered over the model's images do not vectorize here), and every pixel's
      // terms, zero where it has no pair (vectorizes).
#pragma omp simd
      for (int x = 0; x < w; ++x) {
        p_w[x] = c.T_wc * points_c[x];
        inside[x] = kernels::icp_model_pixel(c, p_w[x], &model_pixel[x]);
      }
      for (int x = 0; x < w; ++x) {
        q_w[x] = model_points[model_pixel[x]];
        m_w[x] = model_normals[model_pixel[x]];
      }
#pragma omp simd reduction(+ : n, row_r2, row_distance)
      for (int x = 0; x < w; ++x) {
        const kernels::IcpTerm t = kernels::icp_pair_term(c, points_c[x], normals_c[x], p_w[x],
                                                          inside[x] != 0, q_w[x], m_w[x]);
        // Zero without a pair (chosen, not multiplied: a pixel without a pair may hold
        // anything). Written out: a loop or a lambda here keeps the loop over x scalar.
        const bool in = t.paired;
        const float sw = t.sqrt_weight;
        Jw[x] = in ? sw * t.J.t.x : 0.0f;
        Jw[w + x] = in ? sw * t.J.t.y : 0.0f;
        Jw[2 * w + x] = in ? sw * t.J.t.z : 0.0f;
        Jw[3 * w + x] = in ? sw * t.J.w.x : 0.0f;
        Jw[4 * w + x] = in ? sw * t.J.w.y : 0.0f;
        Jw[5 * w + x] = in ? sw * t.J.w.z : 0.0f;
        rw[x] = in ? sw * t.r : 0.0f;
        row_r2 += in ? t.r * t.r : 0.0f;
        row_distance += in ? t.distance_m : 0.0f;
        n += in;
      }
      int k = 0;
      for (int i = 0; i < 6; ++i) {
        const float* Ji = Jw + i * w;
        for (int j = i; j < 6; ++j) {
          const float* Jj = Jw + j * w;
          float a = 0.0f;
#pragma omp simd reduction(+ : a)
          for (int m = 0; m < w; ++m) a += Ji[m] * Jj[m];
          row_A[k++] = a;
        }
        float b = 0.0f;
#pragma omp simd reduction(+ : b)
        for (int m = 0; m < w; ++m) b += Ji[m] * rw[m];
        row_b[i] = b;
      }
      RowSums& row = sums[y];
      std::copy(row_A, row_A + 21, row.A);
      std::copy(row_b, row_b + 6, row.b);
      row.r2 = row_r2;
      row.distance = row_distance;
      row.inliers = n;
    }
  });
  // The rows summed in row order, in doubles: the same system whatever the thread count.
  icp::Sums sum;
  for (int y = 0; y < h; ++y) {
    const RowSums& row = sums[y];
    sum.add(row.A, row.b, row.r2, row.distance, row.inliers);
  }
  return sum;
}

void Tracker::check_sizes(const PinholeCamera& frame_camera,
                          const PinholeCamera& model_camera) const {
  // Each pyramid level halves both images; every level of both must keep pixels to pair.
  const int coarse = 1 << (params_.levels() - 1);
  const int fw = frame_camera.width / coarse, fh = frame_camera.height / coarse;
  const int mw = model_camera.width / coarse, mh = model_camera.height / coarse;
  if (fw < kMinLevelPx || fh < kMinLevelPx || mw < kMinLevelPx || mh < kMinLevelPx)
    fail(ErrorCode::InvalidArgument,
         "tracking: {}x{} depth images (a {}x{} model) are too small for {} ICP pyramid levels: "
         "the coarsest level would be {}x{} ({}x{} model), at least {}x{} is needed; use fewer "
         "levels (--icp-iterations with fewer entries), --icp-model-subsample 1, or given poses",
         frame_camera.width, frame_camera.height, model_camera.width, model_camera.height,
         params_.levels(), fw, fh, mw, mh, kMinLevelPx, kMinLevelPx);
}

TrackResult Tracker::track(const DepthImage& depth_m, const PinholeCamera& camera,
                           const RaycastResult& model, const Pose& T_wc_init) {
  camera.validate("tracking camera");
  if (depth_m.width() != camera.width || depth_m.height() != camera.height)
    fail(ErrorCode::InvalidArgument, "tracking: the depth image is {}x{} but the camera is {}x{}",
         depth_m.width(), depth_m.height(), camera.width, camera.height);
  if (model.depth_m.width() != model.camera.width || model.depth_m.height() != model.camera.height)
    fail(ErrorCode::InvalidArgument, "tracking: the model is {}x{} but its camera is {}x{}",
         model.depth_m.width(), model.depth_m.height(), model.camera.width, model.camera.height);
  check_sizes(camera, model.camera);
  TrackResult result;
  Stopwatch watch;
  build_pyramid(depth_m, camera, params_, depth_range_, frame_);
  build_model_pyramid(model);
  T_model_cw_ = to_rigid3f(model.T_wc.inverse());
  result.preprocess_ms = watch.lap_ms();
  int64_t valid_pixels = 0;
  for (std::size_t i = 0; i < frame_[0].normals_c.size(); ++i) {
    if (!kernels::is_zero(frame_[0].normals_c.data()[i])) ++valid_pixels;
  }
  icp::align_and_judge(
      params_, [&](int level, const Pose& T) { return reduce(level, T); }, valid_pixels, T_wc_init,
      &result);
  result.icp_ms = watch.lap_ms();
  return result;
}

}  // namespace hivox

#include "hivox/eval/mesh_eval.h"

#include <nanoflann.hpp>

#include <algorithm>
#include <cmath>
#include <random>

#include "core/parallel.h"
#include "hivox/core/device.h"
#include "hivox/core/error.h"

namespace hivox {

void MeshEvalParams::validate() const {
  if (samples < 1 || samples > 100'000'000)
    fail(ErrorCode::InvalidArgument, "mesh evaluation samples must be in 1..1e8, got {}", samples);
  if (thresholds_m.empty())
    fail(ErrorCode::InvalidArgument, "mesh evaluation needs at least one threshold");
  for (double t : thresholds_m)
    if (!(t > 0 && t < 1e3))
      fail(ErrorCode::InvalidArgument, "mesh evaluation thresholds must be > 0 m, got {}", t);
}

Vec3f closest_point_on_triangle(const Vec3f& p, const Vec3f& a, const Vec3f& b, const Vec3f& c) {
  // The Voronoi regions of the triangle's vertices, edges and face, in turn.
  const Vec3f ab = b - a, ac = c - a, ap = p - a;
  const float d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3f bp = p - b;
  const float d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const float vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
  const Vec3f cp = p - c;
  const float d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const float vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
  const float va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const float denom = va + vb + vc;
  if (!(std::abs(denom) > 0)) return a;  // a degenerate triangle: its first corner
  const float v = vb / denom, w = vc / denom;
  return a + ab * v + ac * w;
}

namespace {

double triangle_area(const TriangleMesh& m, const std::array<int32_t, 3>& t) {
  const Vec3f a = m.positions_w[t[0]], b = m.positions_w[t[1]], c = m.positions_w[t[2]];
  return 0.5 * static_cast<double>(norm(cross(b - a, c - a)));
}

struct AnchorCloud {
  std::vector<Vec3f> points;
  std::vector<int32_t> triangle;  ///< the triangle each anchor covers
  std::size_t kdtree_get_point_count() const { return points.size(); }
  float kdtree_get_pt(std::size_t i, std::size_t dim) const {
    return points[i][static_cast<int>(dim)];
  }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};

using AnchorTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, AnchorCloud>,
                                        AnchorCloud, 3, uint32_t>;

DistanceStats summarize(std::vector<double> d) {
  DistanceStats s;
  if (d.empty()) return s;
  double sum = 0, sq = 0;
  for (double v : d) {
    sum += v;
    sq += v * v;
    s.max_m = std::max(s.max_m, v);
  }
  const auto n = static_cast<double>(d.size());
  s.mean_m = sum / n;
  s.rmse_m = std::sqrt(sq / n);
  const std::size_t mid = d.size() / 2;
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(mid), d.end());
  s.median_m = d[mid];
  return s;
}

std::vector<double> distances(const std::vector<Vec3f>& points, const SurfaceDistance& surface) {
  std::vector<double> d(points.size());
  // Far points take longer (more anchors until the answer is exact): dynamic chunks.
  parallel_for(
      Device::cpu(), static_cast<int64_t>(points.size()),
      [&](int64_t i) {
        const auto k = static_cast<std::size_t>(i);
        d[k] = surface.distance(points[k]);
      },
      CpuSchedule::dynamic(512));
  return d;
}

double fraction_within(const std::vector<double>& d, double t) {
  if (d.empty()) return 0;
  return static_cast<double>(std::count_if(d.begin(), d.end(), [t](double v) { return v < t; })) /
         static_cast<double>(d.size());
}

}  // namespace

struct SurfaceDistance::Index {
  const TriangleMesh& mesh;
  AnchorCloud cloud;
  double spacing_m = 0;  ///< every point of a triangle lies within this of one of its anchors
  double exact_within_m = 0;
  std::unique_ptr<AnchorTree> tree;

  explicit Index(const TriangleMesh& m) : mesh(m) {}

  double triangle_distance(int32_t t, const Vec3f& p) const {
    const auto& tri = mesh.triangles[static_cast<std::size_t>(t)];
    const Vec3f q = closest_point_on_triangle(p, mesh.positions_w[tri[0]], mesh.positions_w[tri[1]],
                                              mesh.positions_w[tri[2]]);
    return static_cast<double>(norm(q - p));
  }
};

SurfaceDistance::SurfaceDistance(const TriangleMesh& mesh, double exact_within_m)
    : index_(std::make_unique<Index>(mesh)) {
  index_->exact_within_m = exact_within_m;
  mesh.validate();
  if (mesh.triangles.empty())
    fail(ErrorCode::InvalidArgument, "distance to a mesh without triangles");
  // The spacing: the median longest edge, but coarse enough that large triangles do not need
  // more than about 8 anchors per triangle on average.
  std::vector<float> longest(mesh.triangles.size());
  double area = 0;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    const Vec3f a = mesh.positions_w[tri[0]], b = mesh.positions_w[tri[1]],
                c = mesh.positions_w[tri[2]];
    longest[t] = std::max({norm(b - a), norm(c - b), norm(a - c)});
    area += triangle_area(mesh, tri);
  }
  std::vector<float> sorted = longest;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2),
                   sorted.end());
  const double median = sorted[sorted.size() / 2];
  const double floor_m = std::sqrt(2.0 * area / (8.0 * static_cast<double>(mesh.triangles.size())));
  index_->spacing_m = std::max({median, floor_m, 1e-6});
  const double h = index_->spacing_m;
  AnchorCloud& cloud = index_->cloud;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    const Vec3f a = mesh.positions_w[tri[0]], b = mesh.positions_w[tri[1]],
                c = mesh.positions_w[tri[2]];
    // A barycentric grid of n steps per edge: every point of the triangle lies within the
    // longest edge / n of a grid point (a corner of its sub-triangle).
    const int n = std::max(1, static_cast<int>(std::ceil(longest[t] / h)));
    if (n == 1) {
      cloud.points.push_back((a + b + c) * (1.0f / 3.0f));
      cloud.triangle.push_back(static_cast<int32_t>(t));
      continue;
    }
    for (int i = 0; i <= n; ++i)
      for (int j = 0; i + j <= n; ++j) {
        const float u = static_cast<float>(i) / static_cast<float>(n),
                    v = static_cast<float>(j) / static_cast<float>(n);
        cloud.points.push_back(a + (b - a) * u + (c - a) * v);
        cloud.triangle.push_back(static_cast<int32_t>(t));
      }
  }
  index_->tree =
      std::make_unique<AnchorTree>(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  index_->tree->buildIndex();
}

SurfaceDistance::~SurfaceDistance() = default;

double SurfaceDistance::spacing_m() const {
  return index_->spacing_m;
}

double SurfaceDistance::distance(const Vec3f& p) const {
  const Index& x = *index_;
  const float query[3] = {p.x, p.y, p.z};
  const std::size_t total = x.cloud.points.size();
  std::vector<uint32_t> ids;
  std::vector<float> d2;
  double best = INFINITY;
  // The k nearest anchors' triangles; a triangle closer than the best found so far must have an
  // anchor within best + spacing, so once the k-th anchor is farther than that, best is exact.
  for (std::size_t k = std::min<std::size_t>(8, total);; k = std::min(2 * k, total)) {
    ids.resize(k);
    d2.resize(k);
    const std::size_t found = x.tree->knnSearch(query, k, ids.data(), d2.data());
    for (std::size_t i = 0; i < found; ++i)
      best = std::min(best, x.triangle_distance(x.cloud.triangle[ids[i]], p));
    if (found < k || k == total) return best;
    if (std::sqrt(static_cast<double>(d2[found - 1])) - x.spacing_m >= best) return best;
    // Far from the surface: within one spacing of the exact distance already (the nearest
    // anchor's triangle is no farther than the nearest point plus the spacing).
    if (std::sqrt(static_cast<double>(d2[0])) > x.exact_within_m + x.spacing_m) return best;
  }
}

std::vector<Vec3f> sample_surface(const TriangleMesh& mesh, int64_t count, uint64_t seed) {
  std::vector<double> cumulative(mesh.triangles.size());
  double total = 0;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    total += triangle_area(mesh, mesh.triangles[t]);
    cumulative[t] = total;
  }
  if (!(total > 0))
    fail(ErrorCode::InvalidArgument, "a mesh without surface (no triangle has area)");
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::vector<Vec3f> points(static_cast<std::size_t>(count));
  for (Vec3f& out : points) {
    const double pick = uniform(rng) * total;
    const std::size_t t = std::min<std::size_t>(
        static_cast<std::size_t>(std::upper_bound(cumulative.begin(), cumulative.end(), pick) -
                                 cumulative.begin()),
        cumulative.size() - 1);
    const auto& tri = mesh.triangles[t];
    double u = uniform(rng), v = uniform(rng);
    if (u + v > 1) {
      u = 1 - u;
      v = 1 - v;
    }
    const Vec3f a = mesh.positions_w[tri[0]], b = mesh.positions_w[tri[1]],
                c = mesh.positions_w[tri[2]];
    out = a + (b - a) * static_cast<float>(u) + (c - a) * static_cast<float>(v);
  }
  return points;
}

MeshEvalResult evaluate_mesh(const TriangleMesh& mesh, const TriangleMesh& reference,
                             const MeshEvalParams& params) {
  params.validate();
  MeshEvalResult r;
  const std::vector<Vec3f> on_mesh = sample_surface(mesh, params.samples, params.seed);
  std::vector<Vec3f> on_reference = sample_surface(reference, params.samples, params.seed + 1);
  if (params.reference_filter) {
    const std::size_t all = on_reference.size();
    std::erase_if(on_reference, [&](const Vec3f& p) { return !params.reference_filter(p); });
    r.reference_kept = static_cast<double>(on_reference.size()) / static_cast<double>(all);
    if (on_reference.empty())
      fail(ErrorCode::InvalidArgument,
           "mesh evaluation: the reference filter kept none of the {} reference points", all);
  }
  const double exact_within_m =
      10.0 * *std::max_element(params.thresholds_m.begin(), params.thresholds_m.end());
  const SurfaceDistance to_reference(reference, exact_within_m), to_mesh(mesh, exact_within_m);
  const std::vector<double> acc = distances(on_mesh, to_reference);
  const std::vector<double> comp = distances(on_reference, to_mesh);
  for (double t : params.thresholds_m) {
    FScore f;
    f.threshold_m = t;
    f.precision = fraction_within(acc, t);
    f.recall = fraction_within(comp, t);
    f.fscore =
        f.precision + f.recall > 0 ? 2 * f.precision * f.recall / (f.precision + f.recall) : 0;
    r.fscores.push_back(f);
  }
  r.accuracy = summarize(acc);
  r.completeness = summarize(comp);
  r.chamfer_m = 0.5 * (r.accuracy.mean_m + r.completeness.mean_m);
  r.mesh_samples = static_cast<int64_t>(on_mesh.size());
  r.reference_samples = static_cast<int64_t>(on_reference.size());
  return r;
}

}  // namespace hivox

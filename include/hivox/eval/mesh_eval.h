#pragma once
/// @file
/// A mesh against a reference mesh (`hivox eval mesh`): points sampled uniformly by area on each,
/// and each point's distance to the other mesh's surface (its nearest triangle, exactly). From
/// them: accuracy (mesh samples to the reference), completeness (reference samples to the mesh),
/// their Chamfer mean, and precision, recall and F-score at distance thresholds.

#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "hivox/core/math.h"
#include "hivox/mesh/triangle_mesh.h"

namespace hivox {

struct MeshEvalParams {
  int64_t samples = 1'000'000;  ///< points sampled on each mesh, uniformly by area
  std::vector<double> thresholds_m = {0.005, 0.01};  ///< for precision, recall, F-score
  uint64_t seed = 1;                                 ///< of the sampling
  /// Completeness and recall count only the reference points this accepts (e.g. the part of
  /// the reference the cameras saw: a sequence that shows part of a scene is not incomplete
  /// where it never looked); all when empty. Accuracy and precision are unaffected.
  std::function<bool(const Vec3f&)> reference_filter;

  /// Throws `Error(InvalidArgument)` naming the bad setting.
  void validate() const;
};

/// Distances of the sampled points of one mesh to the other's surface, metres (exact within 10
/// times the largest threshold, at most one mesh edge too long beyond: SurfaceDistance).
struct DistanceStats {
  double mean_m = 0, median_m = 0, rmse_m = 0, max_m = 0;
};

struct FScore {
  double threshold_m = 0;
  double precision = 0;  ///< mesh samples within the threshold of the reference
  double recall = 0;     ///< reference samples within the threshold of the mesh
  double fscore = 0;     ///< 2 P R / (P + R), 0 when both are 0
};

struct MeshEvalResult {
  DistanceStats accuracy;       ///< mesh -> reference
  DistanceStats completeness;   ///< reference -> mesh
  double chamfer_m = 0;         ///< (accuracy.mean_m + completeness.mean_m) / 2
  std::vector<FScore> fscores;  ///< one per threshold, in the params' order
  int64_t mesh_samples = 0, reference_samples = 0;
  double reference_kept = 1.0;  ///< share of the reference samples `reference_filter` accepted
};

/// Evaluates `mesh` against `reference`. Throws `Error(InvalidArgument)` when either has no
/// triangle of positive area.
MeshEvalResult evaluate_mesh(const TriangleMesh& mesh, const TriangleMesh& reference,
                             const MeshEvalParams& params = {});

/// `count` points on `mesh`'s triangles, uniformly by area (a triangle is picked with probability
/// proportional to its area, then a uniform point in it), from `seed`.
std::vector<Vec3f> sample_surface(const TriangleMesh& mesh, int64_t count, uint64_t seed);

/// The closest point of triangle (a, b, c) to `p`.
Vec3f closest_point_on_triangle(const Vec3f& p, const Vec3f& a, const Vec3f& b, const Vec3f& c);

/// Distances to a mesh's surface: a k-d tree (nanoflann) over anchor points that cover every
/// triangle within the anchor spacing (the centroid, or a barycentric grid on larger triangles;
/// the spacing is about the median edge). Near the surface a query takes the nearest anchors'
/// triangles until no farther anchor can hold a closer one: the distance is exact. Beyond
/// `exact_within_m` it takes the triangles of the 8 nearest anchors: the distance is at most one
/// anchor spacing too long (a far point's distance needs no more, and costs no more than a near
/// one's).
class SurfaceDistance {
 public:
  explicit SurfaceDistance(const TriangleMesh& mesh, double exact_within_m = 0.1);
  /// The anchor spacing: the most a distance beyond `exact_within_m` can be too long.
  double spacing_m() const;
  ~SurfaceDistance();
  SurfaceDistance(const SurfaceDistance&) = delete;
  SurfaceDistance& operator=(const SurfaceDistance&) = delete;
  /// Distance from `p` to the nearest triangle, metres.
  double distance(const Vec3f& p) const;

 private:
  struct Index;
  std::unique_ptr<Index> index_;
};

}  // namespace hivox

// The hierarchy on the synthetic desk: where blocks end up, how many there are, and
// how accurate the surface is, against fixed 2 mm and 8 mm grids fused from the same frames.
// Levels and accuracy are judged at points on the true surface (area, not block counts: one
// coarse block covers the area of 64 finest blocks).

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <variant>

#include "hivox/eval/surface_eval.h"
#include "hivox/pipeline/reconstruction.h"
#include "hivox/synth/synthetic_dataset.h"
#include "map/map_invariants.h"
#include "test_util.h"

namespace hivox {
namespace {

struct Outcome {
  std::map<std::string, std::array<double, 3>> level_share;  // per label: finest .. coarsest
  int64_t adaptive_blocks = 0, fine_blocks = 0;
  double adaptive_err = 0, fine_err = 0, coarse_err = 0;
};

Outcome run(const std::string& noise, int frames) {
  SyntheticDataset data(
      parse_synthetic_spec("synthetic:desk?frames=" + std::to_string(frames) + "&noise=" + noise));
  ReconstructionParams adaptive;
  adaptive.map.levels = 3;
  adaptive.map.voxel_size_m = 0.002f;
  adaptive.map.truncation_m = 0.024f;
  adaptive.raycast_every_frame = false;
  adaptive.map.store_color = false;  // geometry only: the same levels and errors, 8 % sooner
  ReconstructionParams fine = adaptive, coarse = adaptive;
  fine.map.levels = 1;
  coarse.map.levels = 1;
  coarse.map.voxel_size_m = 0.008f;
  Reconstruction a(adaptive, data.info().rig), f(fine, data.info().rig), c(coarse, data.info().rig);
  for (std::size_t i = 0; i < data.size(); ++i) {
    const RgbdFrame frame = data.read(i);
    for (Reconstruction* r : {&a, &f, &c}) r->integrate(frame, *frame.T_wc_gt);
  }
  // Reference points on the true surface, seen from six poses along the path.
  std::vector<Vec3f> points;
  std::vector<std::string> labels;
  const PinholeCamera cam = data.camera();
  for (std::size_t i = 0; i < data.size(); i += data.size() / 6) {
    const RenderedFrame clean = data.render_clean(i);
    for (int y = 0; y < cam.height; y += 4)
      for (int x = 0; x < cam.width; x += 4) {
        const float d = clean.depth_m(x, y);
        if (d <= 0.0f || d > 3.0f) continue;
        const Eigen::Vector3d p =
            clean.T_wc * Eigen::Vector3d((x - cam.cx) / cam.fx * d, (y - cam.cy) / cam.fy * d, d);
        points.push_back(
            {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())});
        labels.push_back(data.scene().primitives()[data.scene().closest_primitive(p)].label);
      }
  }
  // "flat top": the points of the table's top face more than one coarsest block from the face's
  // edges and from every object standing on it (a block that also holds part of an object or of
  // the table's 90-degree edge is rightly fine; the table's box comes from the scene).
  const double coarse_block_m = adaptive.map.block_size_at(adaptive.map.levels - 1);
  std::vector<bool> flat_top(points.size(), false);
  for (const Primitive& table : data.scene().primitives()) {
    if (table.label != "table") continue;
    const Box& box = std::get<Box>(table.shape);
    const Eigen::Vector3d top = box.center_w + Eigen::Vector3d(0, 0, box.half_extents_m.z());
    for (std::size_t i = 0; i < points.size(); ++i) {
      const Eigen::Vector3d p(points[i].x, points[i].y, points[i].z);
      if (labels[i] != "table" || std::abs(p.z() - top.z()) > 0.003 ||
          std::abs(p.x() - top.x()) > box.half_extents_m.x() - coarse_block_m ||
          std::abs(p.y() - top.y()) > box.half_extents_m.y() - coarse_block_m)
        continue;
      bool near_object = false;
      for (const Primitive& other : data.scene().primitives())
        if (other.label != "table" && other.label != "floor" && other.label != "wall" &&
            other.label != "table_leg")
          near_object = near_object || sdf(other.shape, p) < coarse_block_m;
      flat_top[i] = !near_object;
    }
  }
  {
    SCOPED_TRACE("the refined map");
    test::expect_hierarchy_consistent(a.map());
  }
  Outcome o;
  const SurfaceEval ea = evaluate_at_points(a.map(), points);
  o.adaptive_err = ea.mean_distance_m;
  o.fine_err = evaluate_at_points(f.map(), points).mean_distance_m;
  o.coarse_err = evaluate_at_points(c.map(), points).mean_distance_m;
  std::map<std::string, std::array<int64_t, 3>> counts;
  for (std::size_t i = 0; i < points.size(); ++i)
    if (ea.per_point[i].level >= 0) {
      ++counts[labels[i]][static_cast<std::size_t>(ea.per_point[i].level)];
      if (flat_top[i]) ++counts["flat top"][static_cast<std::size_t>(ea.per_point[i].level)];
    }
  for (const auto& [label, n] : counts) {
    const double total = static_cast<double>(n[0] + n[1] + n[2]);
    o.level_share[label] = {n[0] / total, n[1] / total, n[2] / total};
  }
  o.adaptive_blocks = a.map().blocks_in_use();
  o.fine_blocks = f.map().blocks_in_use();
  // The measurements, for whoever tunes the criteria next.
  for (const auto& [label, share] : o.level_share)
    std::printf("[ %s ] %-10s levels %.2f %.2f %.2f\n", noise.c_str(), label.c_str(), share[0],
                share[1], share[2]);
  std::printf("[ %s ] blocks %.3f of fixed 2 mm; error %.2fx fixed 2 mm, %.2fx fixed 8 mm\n",
              noise.c_str(), static_cast<double>(o.adaptive_blocks) / o.fine_blocks,
              o.adaptive_err / o.fine_err, o.adaptive_err / o.coarse_err);
  EXPECT_GT(ea.found, static_cast<int64_t>(points.size() * 0.9))
      << "most of the surface is covered";
  return o;
}

void expect_sensible_hierarchy(const Outcome& o, double walls_coarse, double max_err_vs_fine,
                               double max_err_vs_coarse) {
  EXPECT_GE(o.level_share.at("wall")[2], walls_coarse) << "walls stay at the coarsest level";
  EXPECT_GE(o.level_share.at("flat top")[2], 0.8)
      << "the flat table top stays at the coarsest level";
  EXPECT_GE(o.level_share.at("keyboard")[0], 0.5) << "the keyboard reaches the finest level";
  EXPECT_GE(o.level_share.at("blob")[0], 0.25) << "the bumpy blob reaches the finest level";
  EXPECT_LE(o.adaptive_blocks, 0.6 * o.fine_blocks) << "fewer blocks than a fixed finest grid";
  EXPECT_LE(o.adaptive_err, max_err_vs_fine * o.fine_err);
  EXPECT_LE(o.adaptive_err, max_err_vs_coarse * o.coarse_err);
}

TEST(Reconstruction, RefinementTakesTheDatasetsNoiseModel) {
  const SyntheticDataset clean(parse_synthetic_spec("synthetic:desk?frames=2&noise=none"));
  EXPECT_EQ(clean.info().rig.depth_noise.sigma_m(2.0f), 0.0f);
  const Refiner from_rig(RefineParams{}, clean.info().rig.depth_noise);
  EXPECT_EQ(from_rig.noise().sigma_m(2.0f), 0.0f);
  RefineParams own;
  own.noise = SensorNoise::kinect();  // the caller's own model stays
  const Refiner given(own, clean.info().rig.depth_noise);
  EXPECT_FLOAT_EQ(given.noise().sigma_m(2.0f), SensorNoise::kinect().sigma_m(2.0f));
  // The parameters in words name the model in use.
  ReconstructionParams p;
  EXPECT_FALSE(test::contains(p.to_string(&clean.info().rig), "sigma(z)"));
  const CameraRig kinect = CameraRig::registered(clean.info().rig.depth_camera);
  EXPECT_TRUE(test::contains(p.to_string(&kinect), "sigma(z)"));
}

TEST(HierarchyDesk, NoiseFree) {
  // The path sampled at 80 poses instead of 120: without noise, the levels and errors are those
  // of 120 frames (which measured walls ~95 % coarse, floor ~96 %, flat top ~95 %, keyboard ~98 %
  // finest, blocks 0.159 of fixed 2 mm, error 1.20x fixed 2 mm and 0.49x fixed 8 mm) in two
  // thirds of the time. With Kinect noise (below) the number of frames matters: fewer average
  // less of the noise away.
  const Outcome o = run("none", 80);
  // Measured (80 frames, 640x480; the dataset declares no sensor noise, so only the absolute
  // 0.3 / 0.15 mm levels and unmeshable cells apply): walls ~97 % coarse, floor ~95 %, flat table
  // top ~95 %, keyboard ~98 % finest, blocks ~15 % of the fixed 2 mm grid, error ~1.18x fixed
  // 2 mm and ~0.49x fixed 8 mm (the bounds below: 1.25x and 0.6x).
  expect_sensible_hierarchy(o, 0.9, 1.25, 0.6);
  EXPECT_GE(o.level_share.at("floor")[2], 0.85);
}

TEST(HierarchyDesk, KinectNoise) {
  const Outcome o = run("kinect", 120);
  // Measured (120 frames; with 60, the flat table top was only half coarse): walls ~96 % coarse,
  // floor ~92 %, flat table top ~86 %, keyboard ~73 % finest, blocks ~9 % of fixed 2 mm, error
  // ~0.88x fixed 2 mm (noise averages out in the coarser voxels) and ~0.86x fixed 8 mm (itself
  // within 5 % of fixed 2 mm at this noise, so 0.6x of fixed 8 mm cannot hold here).
  expect_sensible_hierarchy(o, 0.9, 1.0, 0.95);
  EXPECT_GE(o.level_share.at("floor")[2], 0.85);
}

}  // namespace
}  // namespace hivox

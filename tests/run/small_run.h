#pragma once
// A small run for tests: the synthetic desk at 160x120 and a two-level map of 1 cm voxels with
// small tables.

#include <string>

#include "hivox/run/runner.h"
#include "hivox/synth/synthetic_dataset.h"

namespace hivox::test {

inline SyntheticDataset small_desk(int frames, const std::string& noise = "none") {
  return SyntheticDataset(parse_synthetic_spec("synthetic:desk?frames=" + std::to_string(frames) +
                                               "&noise=" + noise + "&width=160&height=120"));
}

inline RunParams small_run() {
  RunParams p;
  p.reconstruction.map.levels = 2;
  p.reconstruction.map.voxel_size_m = 0.01f;
  p.reconstruction.map.truncation_m = 0.04f;
  p.reconstruction.map.max_blocks = 1 << 16;
  p.reconstruction.map.buckets_per_level = 1 << 14;
  p.reconstruction.map.excess_per_level = 1 << 14;
  return p;
}

}  // namespace hivox::test

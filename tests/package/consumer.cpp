// my_app.cpp: fuses a built-in synthetic scene, saves the map, loads it again and meshes it.
#include <cstdio>

#include "hivox/core/error.h"
#include "hivox/io/map_file.h"
#include "hivox/mesh/extract_mesh.h"
#include "hivox/run/runner.h"
#include "hivox/synth/synthetic_dataset.h"

int main() {
  try {
    hivox::SyntheticDataset data(
        hivox::parse_synthetic_spec("synthetic:box?frames=5&width=80&height=60&noise=none"));
    hivox::RunParams run;
    run.poses.source = hivox::PoseSource::GroundTruth;
    run.reconstruction.map.voxel_size_m = 0.01f;
    run.reconstruction.map.truncation_m = 0.08f;
    run.map_out = "box.hvx";
    const hivox::RunResult result = hivox::run_reconstruction(data, run);
    const hivox::LoadedMap loaded = hivox::read_map_file("box.hvx");
    const hivox::TriangleMesh mesh = hivox::extract_mesh(*loaded.map);
    std::printf("%zu frames fused, %lld blocks, %lld triangles\n", result.summary.frames_fused,
                static_cast<long long>(loaded.map->blocks_in_use()),
                static_cast<long long>(mesh.triangle_count()));
    return mesh.triangle_count() > 100 ? 0 : 1;
  } catch (const hivox::Error& e) {  // bad settings or files: one line naming them
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
}

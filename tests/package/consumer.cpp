// Uses the installed hivox: fuses a built-in synthetic scene, saves the map, loads it, meshes
// it. Prints one line; exits non-zero when something is wrong.

#include <cstdio>
#include <filesystem>
#include <string>

#include "hivox/core/error.h"
#include "hivox/core/version.h"
#include "hivox/io/map_file.h"
#include "hivox/mesh/extract_mesh.h"
#include "hivox/run/runner.h"
#include "hivox/synth/synthetic_dataset.h"

int main(int argc, char** argv) {
  try {
    const std::filesystem::path map_path =
        argc > 1 ? argv[1] : std::filesystem::temp_directory_path() / "consumer.hvx";
    hivox::SyntheticDataset data(
        hivox::parse_synthetic_spec("synthetic:box?frames=5&width=80&height=60&noise=none"));
    hivox::RunParams run;
    run.poses.source = hivox::PoseSource::GroundTruth;
    run.reconstruction.map.voxel_size_m = 0.01f;
    run.reconstruction.map.truncation_m = 0.08f;
    run.map_out = map_path;
    const hivox::RunResult result = hivox::run_reconstruction(data, run);
    const hivox::LoadedMap loaded = hivox::read_map_file(map_path);
    const hivox::TriangleMesh mesh = hivox::extract_mesh(*loaded.map);
    std::printf("hivox %s: %zu frames fused, %lld blocks, mesh of %lld triangles\n",
                std::string(hivox::library_version()).c_str(), result.summary.frames_fused,
                static_cast<long long>(loaded.map->blocks_in_use()),
                static_cast<long long>(mesh.triangle_count()));
    std::filesystem::remove(map_path);
    return result.summary.frames_fused == 5 && mesh.triangle_count() > 100 ? 0 : 1;
  } catch (const hivox::Error& e) {
    std::fprintf(stderr, "consumer: %s\n", e.what());
    return 1;
  }
}

#include "dataset_options.h"

#include <fmt/format.h>

#include "hivox/core/error.h"

namespace hivox::cli {

void add_dataset_options(CLI::App* cmd, DatasetOptions& options) {
  cmd->add_option("DATASET", options.dataset,
                  "dataset folder (TUM, 7-Scenes or InfiniTAM layout; detected automatically) or a "
                  "built-in scene: synthetic:NAME[?frames=N&noise=kinect|none&width=W&height=H]")
      ->required()
      ->type_name("");
  cmd->add_option("--preset", options.params.preset,
                  "camera preset to use instead of the folder's intrinsics (list below)")
      ->type_name("NAME");
  options.depth_scale_option =
      cmd->add_option(
             "--depth-scale", options.params.depth_scale,
             "raw depth units per metre, e.g. 5000 (TUM, ICL-NUIM) or 1000 (millimetres: 7-Scenes, "
             "Redwood, RealSense); overrides the file and preset")
          ->type_name("S");
  cmd->add_option("--intrinsics", options.intrinsics,
                  "intrinsics.json to use instead of the folder's own "
                  "({\"fx\",\"fy\",\"cx\",\"cy\",\"width\",\"height\",\"depth_scale\"})")
      ->type_name("FILE");
  cmd->add_option("--max-frames", options.params.max_frames,
                  "use the first N frames only (0 = all)")
      ->check(CLI::NonNegativeNumber)
      ->type_name("N");
  cmd->add_flag("!--keep-distortion", options.params.undistort,
                "use frames as stored even when the calibration has lens distortion (by default "
                "it is removed from every frame as it is read)");
}

std::string dataset_help() {
  std::string presets;
  for (const CameraPreset& p : camera_presets())
    presets += fmt::format("  {:<13} {} (fx={:g} fy={:g} cx={:g} cy={:g}, depth scale {:g})\n",
                           p.name, p.description, p.camera.fx, p.camera.fy, p.camera.cx,
                           p.camera.cy, p.depth_scale);
  return "Layouts (detected from the folder):\n"
         "  TUM        associations.txt (t_rgb rgb/F t_depth depth/F) or rgb.txt + depth.txt,\n"
         "             optional groundtruth.txt (matched within 20 ms) and intrinsics.json\n"
         "  7-Scenes   seq-NN/frame-NNNNNN.{color.png,depth.png,pose.txt}, depth in mm\n"
         "  InfiniTAM  calib.txt ('affine a b' depth line) + 0000.pgm/0000.ppm frames\n"
         "             (or PNG), in the folder or in Frames/\n"
         "Intrinsics come from --intrinsics, --preset, the folder's intrinsics.json, the layout's\n"
         "default or a guess from the folder name (fr1/freiburg1 -> tum_fr1), in that order.\n"
         "Lens distortion (intrinsics.json 'distortion_k1k2p1p2k3', the fr1/fr2 presets) is\n"
         "removed from depth and registered colour as frames are read (--keep-distortion: not).\n"
         "Camera presets (all 640x480):\n" +
         presets;
}

std::unique_ptr<DatasetReader> open_dataset(const DatasetOptions& options) {
  DatasetParams params = options.params;
  // 0 means "from the dataset" in DatasetParams, but typed on the command line it is a mistake.
  if (options.depth_scale_option != nullptr && options.depth_scale_option->count() > 0 &&
      !(params.depth_scale > 0))
    fail(ErrorCode::InvalidArgument,
         "--depth-scale must be > 0 raw units per metre (e.g. 5000 for TUM, 1000 for mm), got {}",
         params.depth_scale);
  params.intrinsics_path = options.intrinsics;
  return hivox::open_dataset(options.dataset, params);
}

}  // namespace hivox::cli

// `hivox info DATASET`: opens a dataset the way every other command will and prints what it
// found, so that a wrong layout, camera or depth scale shows up before a long run. `hivox
// devices`: where runs can go (--device).

#include <cstdio>
#include <memory>
#include <string>

#include "commands.h"
#include "dataset_options.h"
#include "hivox/io/dataset.h"
#include "hivox/run/devices.h"

namespace hivox::cli {

void add_info_command(CLI::App& app) {
  auto options = std::make_shared<DatasetOptions>();
  CLI::App* cmd = app.add_subcommand(
      "info",
      "Show what hivox finds in a dataset folder (layout, frame count, resolution, intrinsics, "
      "depth scale and depth range, colour, ground-truth poses and warnings) or in a map file "
      "(.hvx: levels, blocks per level, memory, bounding box, settings).");
  add_dataset_options(cmd, *options);
  cmd->footer(dataset_help() +
              "Examples:\n"
              "  hivox info ../shared/data/tum_fr1_rpy\n"
              "  hivox info ~/data/rgbd_dataset_freiburg2_desk --preset tum_fr2\n"
              "  hivox info ~/data/chess --depth-scale 1000\n"
              "  hivox info rpy.hvx\n"
              "A median depth outside 0.1-10 m is reported as a warning with the likely depth "
              "scale.");
  cmd->callback([options] {
    if (print_map_file_info(options->dataset)) return;
    const std::unique_ptr<DatasetReader> reader = open_dataset(*options);
    std::fputs(describe_dataset(*reader).c_str(), stdout);
  });
}

void add_devices_command(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand(
      "devices",
      "List the devices runs can use (--device): the CPU with its threads, and in builds with "
      "the CUDA loop each CUDA device with its memory (free now), compute capability and "
      "multiprocessors.");
  cmd->footer(
      "Examples:\n"
      "  hivox devices\n"
      "  hivox reconstruct ../shared/data/tum_fr1_rpy --device cuda:1\n");
  cmd->callback([] {
    const DeviceList list = list_devices();
    for (const DeviceInfo& d : list.devices)
      std::printf("%-8s %s\n", d.device.to_string().c_str(), d.to_string().c_str());
    if (!list.cuda_note.empty()) std::printf("%-8s %s\n", "cuda", list.cuda_note.c_str());
  });
}

}  // namespace hivox::cli

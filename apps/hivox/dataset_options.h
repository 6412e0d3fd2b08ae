#pragma once
// Options every command that reads a dataset shares: the dataset itself and how to calibrate it.

#include <memory>
#include <string>

#include <CLI/CLI.hpp>

#include "hivox/core/dataset.h"
#include "hivox/io/dataset.h"

namespace hivox::cli {

struct DatasetOptions {
  std::string dataset;
  DatasetParams params;
  std::string intrinsics;
  CLI::Option* depth_scale_option = nullptr;
};

/// Adds DATASET and --preset, --depth-scale, --intrinsics, --max-frames to `cmd`.
void add_dataset_options(CLI::App* cmd, DatasetOptions& options);

/// Help text on layouts, calibration order and camera presets.
std::string dataset_help();

/// Opens the dataset the options describe (errors name the file or option).
std::unique_ptr<DatasetReader> open_dataset(const DatasetOptions& options);

}  // namespace hivox::cli

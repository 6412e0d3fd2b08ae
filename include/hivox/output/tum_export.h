#pragma once
/// @file
/// Writes any `DatasetReader` (typically a synthetic scene) as a TUM RGB-D sequence that TUM
/// tools and hivox's own TUM reader read back:
///
///     DIR/rgb/T.png         8-bit RGB colour (when the reader has colour)
///     DIR/depth/T.png       16-bit depth, value / depth_scale = metres, 0 = invalid
///     DIR/rgb.txt           `t rgb/T.png` per frame
///     DIR/depth.txt         `t depth/T.png` per frame
///     DIR/associations.txt  `t_rgb rgb/T.png t_depth depth/T.png` per frame
///     DIR/groundtruth.txt   `t tx ty tz qx qy qz qw`, camera-to-world (when poses are known)
///     DIR/intrinsics.json   fx fy cx cy width height depth_scale
///
/// T is the frame timestamp with 6 decimals (seconds).

#include <cstddef>
#include <filesystem>
#include <functional>

#include "hivox/core/dataset.h"

namespace hivox {

/// Called after each written frame with (frames written, frames to write).
using ExportProgress = std::function<void(std::size_t done, std::size_t total)>;

/// Exports the first `frames` frames of `reader` (0 = all) to the folder `dir`, written whole
/// (OutputFolder): a `dir` that holds files already is refused unless `overwrite`, and then
/// replaced as a whole. Depth beyond the 16-bit range (65535 / depth_scale metres) is written as
/// invalid, with a warning. Throws `Error` naming the file that could not be written, or
/// `Error(InvalidArgument)` for depth_scale <= 0.
void export_tum(DatasetReader& reader, const std::filesystem::path& dir, double depth_scale = 5000,
                std::size_t frames = 0, const ExportProgress& progress = {},
                bool overwrite = false);

}  // namespace hivox

#pragma once
/// @file
/// Legends drawn into the PNG renders, so that a picture says what its colours mean: a strip
/// below a level picture with each level's colour and voxel size, and below a depth picture the
/// colour ramp with the depths of its ends. Text is drawn with a small built-in vector font
/// (stb_easy_font).

#include <string_view>

#include "hivox/core/image.h"

namespace hivox {

/// Draws `text` with its top-left corner at (x, y), each font unit `scale` pixels; what falls
/// outside the image is clipped.
void draw_text(ColorImage& image, int x, int y, std::string_view text, Rgb8 color, int scale = 1);
/// The width of `text` in pixels at `scale`.
int text_width(std::string_view text, int scale = 1);

/// `image` with a strip below it: a swatch in `level_color(l)` and the voxel size of each level
/// (`voxel_size_m` at level 0, doubling per level), finest first.
ColorImage add_level_legend(const ColorImage& image, int levels, float voxel_size_m);

/// `image` with a strip below it: the colour ramp of `render_depth` from `min_m` to `max_m`, with
/// both ends labelled in metres.
ColorImage add_depth_scale(const ColorImage& image, float min_m, float max_m);

}  // namespace hivox

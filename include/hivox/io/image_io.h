#pragma once
/// @file
/// Image files: PNG (libpng), JPEG (libjpeg-turbo) and binary PNM (PGM/PPM). Every failure is an
/// `Error` whose message names the file and the problem.

#include <cstdint>
#include <filesystem>
#include <vector>

#include "hivox/core/image.h"

namespace hivox {

/// Reads a 16-bit single-channel depth image (PNG or 16-bit PGM). A colour image, an 8-bit image
/// or an unreadable file is an error naming the file and what was found.
Image<uint16_t> read_depth16(const std::filesystem::path& path);

/// Reads a colour image: PNG (grey, RGB, with or without alpha, 8 or 16 bit), JPEG, or PPM/PGM.
ColorImage read_color(const std::filesystem::path& path);

/// Converts raw depth to metres: `raw / depth_scale`; 0 and `invalid_raw` (e.g. 65535 in
/// 7-Scenes) become 0 (invalid). `depth_offset_m` is added to valid values.
DepthImage depth_to_metres(const Image<uint16_t>& raw, double depth_scale, uint16_t invalid_raw = 0,
                           double depth_offset_m = 0.0);

/// Converts metric depth to raw units (rounded, clamped to 1..65535; 0 stays invalid).
Image<uint16_t> depth_to_raw(const DepthImage& depth_m, double depth_scale);

void write_png(const std::filesystem::path& path, const Image<uint16_t>& image);
void write_png(const std::filesystem::path& path, const Image<uint8_t>& image);
void write_png(const std::filesystem::path& path, const ColorImage& image);
/// The PNG file's bytes for `image` (e.g. to serve it); `compression_level` 0..9 (zlib's).
std::vector<uint8_t> encode_png(const ColorImage& image, int compression_level = 3);

}  // namespace hivox

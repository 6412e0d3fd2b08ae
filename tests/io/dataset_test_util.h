#pragma once
// Helpers for the dataset tests: small self-written datasets in every layout.

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include <fmt/format.h>

#include "hivox/core/error.h"
#include "hivox/core/image.h"
#include "hivox/io/image_io.h"
#include "hivox/io/intrinsics_io.h"
#include "test_util.h"

namespace hivox::test {

namespace fs = std::filesystem;

/// Asserts the code and that the message contains every one of `parts`.
template <typename F>
void expect_error(F&& f, ErrorCode code, std::initializer_list<std::string> parts) {
  const Error e = error_of(std::forward<F>(f));
  EXPECT_EQ(e.code(), code) << "message: " << e.what();
  const std::string message = e.what();
  for (const std::string& part : parts)
    EXPECT_NE(message.find(part), std::string::npos)
        << "message '" << message << "' lacks '" << part << "'";
}

constexpr int kWidth = 8, kHeight = 6;

/// The camera of the small test images.
inline PinholeCamera tiny_camera() {
  return PinholeCamera{10.0f, 10.0f, 3.5f, 2.5f, kWidth, kHeight};
}

/// Raw depth `base + 10 x + y`: every pixel different, so a test sees which file it got.
inline Image<uint16_t> raw_depth(uint16_t base, int width = kWidth, int height = kHeight) {
  Image<uint16_t> d(width, height);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) d(x, y) = static_cast<uint16_t>(base + 10 * x + y);
  return d;
}

/// Colour `{tag, 10 x, 10 y}`.
inline ColorImage colour(uint8_t tag, int width = kWidth, int height = kHeight) {
  ColorImage c(width, height);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      c(x, y) = {tag, static_cast<uint8_t>(10 * x), static_cast<uint8_t>(10 * y)};
  return c;
}

inline void write_depth(const fs::path& path, const Image<uint16_t>& d) {
  fs::create_directories(path.parent_path());
  write_png(path, d);
}
inline void write_colour(const fs::path& path, const ColorImage& c) {
  fs::create_directories(path.parent_path());
  write_png(path, c);
}

inline void write_intrinsics(const fs::path& path, const PinholeCamera& camera,
                             double depth_scale) {
  fs::create_directories(path.parent_path());
  IntrinsicsFile f;
  f.camera = camera;
  f.depth_scale = depth_scale;
  write_intrinsics_json(path, f);
}

/// 16-bit binary PGM (big-endian samples), as InfiniTAM writes depth.
inline void write_pgm16(const fs::path& path, const Image<uint16_t>& d) {
  fs::create_directories(path.parent_path());
  std::ofstream f(path, std::ios::binary);
  f << "P5\n" << d.width() << " " << d.height() << "\n65535\n";
  for (std::size_t i = 0; i < d.size(); ++i) {
    const char bytes[2] = {static_cast<char>(d.data()[i] >> 8),
                           static_cast<char>(d.data()[i] & 0xFF)};
    f.write(bytes, 2);
  }
}

inline void write_ppm(const fs::path& path, const ColorImage& c) {
  fs::create_directories(path.parent_path());
  std::ofstream f(path, std::ios::binary);
  f << "P6\n" << c.width() << " " << c.height() << "\n255\n";
  f.write(reinterpret_cast<const char*>(c.data()), static_cast<std::streamsize>(c.size() * 3));
}

/// A valid TUM-layout set with 3 frames: depth at t = 1.00, 1.10, 1.20 (raw 5000 + 1000 i + ...,
/// scale 5000), colour 10 ms earlier, and ground truth within 20 ms of frames 0 and 1 only.
inline void write_small_tum(const fs::path& dir) {
  for (int i = 0; i < 3; ++i) {
    write_depth(dir / fmt::format("depth/d{}.png", i),
                raw_depth(static_cast<uint16_t>(5000 + 1000 * i)));
    write_colour(dir / fmt::format("rgb/c{}.png", i), colour(static_cast<uint8_t>(i)));
  }
  write_text(dir / "associations.txt",
             "# t_rgb rgb_file t_depth depth_file\n"
             "0.99 rgb/c0.png 1.00 depth/d0.png\n"
             "1.09 rgb/c1.png 1.10 depth/d1.png\n"
             "1.19 rgb/c2.png 1.20 depth/d2.png\n");
  write_text(dir / "groundtruth.txt",
             "# timestamp tx ty tz qx qy qz qw\n"
             "0.5 0 0 0 0 0 0 1\n"
             "1.005 1 2 3 0 0 0 1\n"
             "1.119 4 5 6 0 0 0.7071067811865476 0.7071067811865476\n"
             "1.179 7 8 9 0 0 0 1\n"
             "1.221 7 8 9 0 0 0 1\n");
  write_intrinsics(dir / "intrinsics.json", tiny_camera(), 5000.0);
}

}  // namespace hivox::test

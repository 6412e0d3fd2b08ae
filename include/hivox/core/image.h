#pragma once
/// @file
/// Image containers. `Image<T>` owns row-major pixels; `ImageView<T>` is a plain-data view for
/// kernels (host or device). Depth images hold metres as float, 0 = invalid.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "hivox/core/hd.h"

namespace hivox {

/// The largest image side hivox accepts (cameras, image files): sizes are checked against it
/// before anything is allocated, so a corrupt header is an error naming its file, not an
/// allocation of terabytes.
inline constexpr int kMaxImageSide = 16384;

struct Rgb8 {
  uint8_t r = 0, g = 0, b = 0;
};
inline bool operator==(const Rgb8& a, const Rgb8& b) {
  return a.r == b.r && a.g == b.g && a.b == b.b;
}

template <typename T>
struct ImageView {
  T* data = nullptr;
  int width = 0;
  int height = 0;
  HIVOX_HD T& operator()(int x, int y) const {
    return data[static_cast<std::size_t>(y) * width + x];
  }
  HIVOX_HD bool inside(int x, int y) const { return x >= 0 && y >= 0 && x < width && y < height; }
  HIVOX_HD bool empty() const { return data == nullptr || width == 0 || height == 0; }
};

template <typename T>
class Image {
 public:
  Image() = default;
  Image(int width, int height, T fill = T{})
      : width_(width), height_(height), pixels_(static_cast<std::size_t>(width) * height, fill) {}

  int width() const { return width_; }
  int height() const { return height_; }
  bool empty() const { return pixels_.empty(); }
  std::size_t size() const { return pixels_.size(); }
  T* data() { return pixels_.data(); }
  const T* data() const { return pixels_.data(); }
  T& operator()(int x, int y) { return pixels_[static_cast<std::size_t>(y) * width_ + x]; }
  const T& operator()(int x, int y) const {
    return pixels_[static_cast<std::size_t>(y) * width_ + x];
  }
  bool inside(int x, int y) const { return x >= 0 && y >= 0 && x < width_ && y < height_; }
  void fill(const T& value) { std::fill(pixels_.begin(), pixels_.end(), value); }
  void resize(int width, int height, T fill = T{}) {
    width_ = width;
    height_ = height;
    pixels_.assign(static_cast<std::size_t>(width) * height, fill);
  }

  ImageView<T> view() { return {pixels_.data(), width_, height_}; }
  ImageView<const T> view() const { return {pixels_.data(), width_, height_}; }

 private:
  int width_ = 0;
  int height_ = 0;
  std::vector<T> pixels_;
};

using DepthImage = Image<float>;  ///< metres, 0 = invalid
using ColorImage = Image<Rgb8>;

}  // namespace hivox

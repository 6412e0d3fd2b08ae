#include "hivox/output/legend.h"

#include <algorithm>
#include <string>
#include <vector>

#include <fmt/format.h>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#include <stb_easy_font.h>  // static functions: the header is its own implementation
#pragma GCC diagnostic pop

#include "hivox/raycast/render.h"

namespace hivox {

namespace {

constexpr Rgb8 kStripColor{24, 26, 30};
constexpr Rgb8 kTextColor{230, 232, 236};

/// Font units per line of text (stb_easy_font's capital height is 7, with descenders 9).
constexpr int kLineUnits = 12;

/// The scale of legend text for an image `width` pixels wide: readable at 320 px and at 1280.
int legend_scale(int width) {
  return std::clamp(width / 320, 1, 4);
}

/// `image` with `strip_height` rows of the strip colour below it.
ColorImage with_strip(const ColorImage& image, int strip_height) {
  ColorImage out(image.width(), image.height() + strip_height, kStripColor);
  for (int y = 0; y < image.height(); ++y)
    std::copy(&image(0, y), &image(0, y) + image.width(), &out(0, y));
  return out;
}

void fill_rect(ColorImage& image, int x0, int y0, int x1, int y1, Rgb8 color) {
  x0 = std::max(x0, 0);
  y0 = std::max(y0, 0);
  x1 = std::min(x1, image.width());
  y1 = std::min(y1, image.height());
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) image(x, y) = color;
}

std::string metres(float m) {
  return fmt::format("{:.2f} m", m);
}

}  // namespace

void draw_text(ColorImage& image, int x, int y, std::string_view text, Rgb8 color, int scale) {
  std::string s(text);
  // About 270 bytes per character (stb_easy_font's estimate).
  std::vector<char> buffer(300 * (s.size() + 1));
  const int quads =
      stb_easy_font_print(0, 0, s.data(), nullptr, buffer.data(), static_cast<int>(buffer.size()));
  struct Vertex {
    float x, y, z;
    unsigned char rgba[4];
  };
  const auto* v = reinterpret_cast<const Vertex*>(buffer.data());
  for (int q = 0; q < quads; ++q) {
    const Vertex* c = v + 4 * q;  // axis-aligned: corners 0 and 2 span it
    fill_rect(image, x + static_cast<int>(c[0].x * scale), y + static_cast<int>(c[0].y * scale),
              x + static_cast<int>(c[2].x * scale), y + static_cast<int>(c[2].y * scale), color);
  }
}

int text_width(std::string_view text, int scale) {
  std::string s(text);
  return stb_easy_font_width(s.data()) * scale;
}

ColorImage add_level_legend(const ColorImage& image, int levels, float voxel_size_m) {
  const int scale = legend_scale(image.width());
  const int pad = 4 * scale, line = kLineUnits * scale;
  ColorImage out = with_strip(image, line + 2 * pad);
  int x = pad;
  const int y = image.height() + pad;
  for (int l = 0; l < levels; ++l) {
    const int swatch = 8 * scale;
    fill_rect(out, x, y + scale, x + swatch, y + scale + swatch, level_color(l));
    x += swatch + 3 * scale;
    const std::string label = fmt::format(
        "level {}: {:g} mm{}", l, 1000.0 * voxel_size_m * (1 << l), l == 0 ? " (finest)" : "");
    draw_text(out, x, y + scale, label, kTextColor, scale);
    x += text_width(label, scale) + 10 * scale;
  }
  return out;
}

ColorImage add_depth_scale(const ColorImage& image, float min_m, float max_m) {
  const int scale = legend_scale(image.width());
  const int pad = 4 * scale, line = kLineUnits * scale;
  ColorImage out = with_strip(image, line + 2 * pad);
  const int y = image.height() + pad;
  const std::string near = metres(min_m), far = metres(max_m);
  draw_text(out, pad, y + scale, near, kTextColor, scale);
  const int far_x = out.width() - pad - text_width(far, scale);
  draw_text(out, far_x, y + scale, far, kTextColor, scale);
  const int x0 = 2 * pad + text_width(near, scale), x1 = far_x - pad;
  for (int x = x0; x < x1; ++x) {
    const Rgb8 c =
        depth_ramp_color(static_cast<float>(x - x0) / static_cast<float>(std::max(x1 - x0 - 1, 1)));
    fill_rect(out, x, y, x + 1, y + 9 * scale, c);
  }
  return out;
}

}  // namespace hivox

// Legends in the PNG renders: the picture above stays as it was, each level's swatch is there in
// its colour, the depth strip runs the render's ramp from near to far, and the labels are drawn.

#include "hivox/output/legend.h"

#include <gtest/gtest.h>

#include "hivox/raycast/render.h"

namespace hivox {
namespace {

constexpr Rgb8 kText{230, 232, 236};

int64_t count(const ColorImage& image, Rgb8 color, int from_row = 0) {
  int64_t n = 0;
  for (int y = from_row; y < image.height(); ++y)
    for (int x = 0; x < image.width(); ++x) n += image(x, y) == color;
  return n;
}

ColorImage picture(int w, int h) {
  ColorImage image(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      image(x, y) = {static_cast<uint8_t>(x), static_cast<uint8_t>(y), 99};
  return image;
}

void expect_top_unchanged(const ColorImage& out, const ColorImage& in) {
  ASSERT_EQ(out.width(), in.width());
  ASSERT_GT(out.height(), in.height());
  EXPECT_LT(out.height(), in.height() + in.height() / 4);  // a strip, not a second picture
  for (int y = 0; y < in.height(); ++y)
    for (int x = 0; x < in.width(); ++x) ASSERT_EQ(out(x, y), in(x, y)) << x << "," << y;
}

TEST(Legend, LevelsGetASwatchAndALabelEach) {
  const ColorImage in = picture(640, 480);
  const ColorImage out = add_level_legend(in, 3, 0.002f);
  expect_top_unchanged(out, in);
  const int scale = 2;  // at 640 px
  for (int l = 0; l < 3; ++l)
    EXPECT_EQ(count(out, level_color(l), in.height()), 64 * scale * scale) << "level " << l;
  EXPECT_EQ(count(out, level_color(3), in.height()), 0);  // no fourth level
  EXPECT_GT(count(out, kText, in.height()), 500);         // three labels
  // A single level: one swatch, a shorter label.
  const ColorImage one = add_level_legend(in, 1, 0.005f);
  EXPECT_EQ(count(one, level_color(0), in.height()), 64 * scale * scale);
  EXPECT_EQ(count(one, level_color(1), in.height()), 0);
  EXPECT_LT(count(one, kText, in.height()), count(out, kText, in.height()));
}

TEST(Legend, DepthScaleRunsTheRampFromNearToFar) {
  const ColorImage in = picture(320, 240);
  const ColorImage out = add_depth_scale(in, 0.5f, 3.25f);
  expect_top_unchanged(out, in);
  // The row through the middle of the bar: the ramp's first colour at its left end, the last at
  // its right end, every colour a ramp colour in order of depth.
  const int y = in.height() + 4 + 4;
  int first = -1, last = -1;
  for (int x = 0; x < out.width(); ++x)
    if (!(out(x, y) == kText) && !(out(x, y) == Rgb8{24, 26, 30})) {
      if (first < 0) first = x;
      last = x;
    }
  ASSERT_GT(last - first, out.width() / 2);
  EXPECT_EQ(out(first, y), depth_ramp_color(0.0f));
  EXPECT_EQ(out(last, y), depth_ramp_color(1.0f));
  EXPECT_NEAR(out((first + last) / 2, y).r, depth_ramp_color(0.5f).r, 3);  // within a pixel
  // Both ends are labelled (the text's pixels left and right of the bar).
  int64_t left = 0, right = 0;
  for (int yy = in.height(); yy < out.height(); ++yy)
    for (int x = 0; x < out.width(); ++x)
      if (out(x, yy) == kText) (x < first ? left : right) += 1;
  EXPECT_GT(left, 20);
  EXPECT_GT(right, 20);
}

TEST(Legend, TextIsDrawnAndClipped) {
  ColorImage image(60, 20, Rgb8{});
  draw_text(image, 2, 2, "0.92 m", kText, 1);
  const int64_t drawn = count(image, kText);
  EXPECT_GT(drawn, 20);
  EXPECT_GT(text_width("0.92 m"), text_width("0.9"));
  EXPECT_EQ(text_width("ab", 2), 2 * text_width("ab", 1));
  // Off the image: clipped, nothing written out of bounds (the sanitizer build checks).
  draw_text(image, 55, 15, "clipped text", kText, 3);
  draw_text(image, -100, -100, "x", kText, 1);
  EXPECT_GE(count(image, kText), drawn);
}

}  // namespace
}  // namespace hivox

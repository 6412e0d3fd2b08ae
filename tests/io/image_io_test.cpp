#include "hivox/io/image_io.h"

#include <gtest/gtest.h>

#include <fstream>

#include "hivox/core/error.h"
#include "test_util.h"

namespace hivox {
namespace {

using test::TempDir;

TEST(ImageIo, Depth16PngRoundTrip) {
  TempDir dir;
  Image<uint16_t> depth(37, 21);
  for (int y = 0; y < depth.height(); ++y)
    for (int x = 0; x < depth.width(); ++x)
      depth(x, y) = static_cast<uint16_t>(x * 1000 + y * 7 + 1);
  depth(3, 4) = 65535;
  write_png(dir / "d.png", depth);
  const Image<uint16_t> back = read_depth16(dir / "d.png");
  ASSERT_EQ(back.width(), 37);
  ASSERT_EQ(back.height(), 21);
  for (std::size_t i = 0; i < depth.size(); ++i) ASSERT_EQ(back.data()[i], depth.data()[i]);
}

TEST(ImageIo, ColorPngRoundTrip) {
  TempDir dir;
  ColorImage c(5, 3);
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 5; ++x)
      c(x, y) = {static_cast<uint8_t>(x * 50), static_cast<uint8_t>(y * 80), 200};
  write_png(dir / "c.png", c);
  const ColorImage back = read_color(dir / "c.png");
  ASSERT_EQ(back.width(), 5);
  for (std::size_t i = 0; i < c.size(); ++i) ASSERT_EQ(back.data()[i], c.data()[i]);
}

TEST(ImageIo, GreyPngReadsAsColor) {
  TempDir dir;
  Image<uint8_t> g(4, 4, 77);
  write_png(dir / "g.png", g);
  const ColorImage back = read_color(dir / "g.png");
  EXPECT_EQ(back(2, 2), (Rgb8{77, 77, 77}));
}

TEST(ImageIo, PgmAndPpm) {
  TempDir dir;
  {
    std::ofstream f(dir / "d.pgm", std::ios::binary);
    f << "P5\n# comment\n2 1\n65535\n";
    const unsigned char px[] = {0x12, 0x34, 0xFF, 0xFE};  // big-endian samples
    f.write(reinterpret_cast<const char*>(px), 4);
  }
  const Image<uint16_t> d = read_depth16(dir / "d.pgm");
  ASSERT_EQ(d.width(), 2);
  EXPECT_EQ(d(0, 0), 0x1234);
  EXPECT_EQ(d(1, 0), 0xFFFE);
  {
    std::ofstream f(dir / "c.ppm", std::ios::binary);
    f << "P6 1 1 255\n";
    const unsigned char px[] = {10, 20, 30};
    f.write(reinterpret_cast<const char*>(px), 3);
  }
  EXPECT_EQ(read_color(dir / "c.ppm")(0, 0), (Rgb8{10, 20, 30}));
}

TEST(ImageIo, DepthConversion) {
  Image<uint16_t> raw(3, 1);
  raw(0, 0) = 0;
  raw(1, 0) = 5000;
  raw(2, 0) = 65535;
  const DepthImage tum = depth_to_metres(raw, 5000.0);
  EXPECT_EQ(tum(0, 0), 0.0f);
  EXPECT_FLOAT_EQ(tum(1, 0), 1.0f);
  EXPECT_NEAR(tum(2, 0), 13.107f, 1e-3f);
  const DepthImage seven = depth_to_metres(raw, 1000.0, 65535);
  EXPECT_FLOAT_EQ(seven(1, 0), 5.0f);
  EXPECT_EQ(seven(2, 0), 0.0f);  // 65535 = invalid in 7-Scenes
  const Image<uint16_t> back = depth_to_raw(tum, 5000.0);
  EXPECT_EQ(back(1, 0), 5000);
  EXPECT_EQ(back(0, 0), 0);
  EXPECT_TRUE(test::contains(test::message_of([&] { depth_to_metres(raw, 0.0); }), "depth_scale"));
  EXPECT_TRUE(test::contains(test::message_of([&] { depth_to_metres(raw, -5.0); }), "depth_scale"));
}

TEST(ImageIo, BadInputNamesFileAndProblem) {
  TempDir dir;
  const auto missing = (dir / "nope.png").string();
  std::string e = test::message_of([&] { read_depth16(missing); });
  EXPECT_TRUE(test::contains(e, missing)) << e;
  EXPECT_TRUE(test::contains(e, "does not exist")) << e;

  ColorImage c(4, 4);
  write_png(dir / "colour.png", c);
  e = test::message_of([&] { read_depth16(dir / "colour.png"); });
  EXPECT_TRUE(test::contains(e, "colour.png")) << e;
  EXPECT_TRUE(test::contains(e, "8-bit RGB")) << e;

  Image<uint8_t> g8(4, 4);
  write_png(dir / "grey8.png", g8);
  e = test::message_of([&] { read_depth16(dir / "grey8.png"); });
  EXPECT_TRUE(test::contains(e, "8-bit grey")) << e;

  // A truncated PNG: valid signature, then garbage.
  Image<uint16_t> d(64, 64, 1234);
  write_png(dir / "full.png", d);
  {
    std::ifstream in(dir / "full.png", std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), {});
    std::ofstream(dir / "cut.png", std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  }
  e = test::message_of([&] { read_depth16(dir / "cut.png"); });
  EXPECT_TRUE(test::contains(e, "cut.png")) << e;

  test::write_text(dir / "text.png", "this is not an image");
  e = test::message_of([&] { read_color(dir / "text.png"); });
  EXPECT_TRUE(test::contains(e, "not a PNG")) << e;

  e = test::message_of([&] { read_color(dir.path()); });
  EXPECT_TRUE(test::contains(e, "directory")) << e;
}

TEST(ImageIo, RealJpegAndDepth) {
  HIVOX_REQUIRE_DATASET(dir, "tum_fr1_rpy");
  const ColorImage c = read_color(dir / "rgb" / "1305031229.528748.jpg");
  EXPECT_EQ(c.width(), 640);
  EXPECT_EQ(c.height(), 480);
  const Image<uint16_t> d = read_depth16(dir / "depth" / "1305031229.528784.png");
  EXPECT_EQ(d.width(), 640);
  std::string e = test::message_of([&] { read_depth16(dir / "rgb" / "1305031229.528748.jpg"); });
  EXPECT_TRUE(test::contains(e, "JPEG")) << e;

  // Cut in half, the JPEG would decode with a grey lower half; it is an error instead.
  test::TempDir tmp;
  const std::filesystem::path cut = tmp / "cut.jpg";
  std::filesystem::copy_file(dir / "rgb" / "1305031229.528748.jpg", cut);
  std::filesystem::resize_file(cut, std::filesystem::file_size(cut) / 2);
  e = test::message_of([&] { read_color(cut); });
  EXPECT_TRUE(test::contains(e, "cut.jpg")) << e;
  EXPECT_TRUE(test::contains(e, "Premature end")) << e;
}

}  // namespace
}  // namespace hivox

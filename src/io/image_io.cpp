#include "hivox/io/image_io.h"

#include <png.h>
// clang-format off
#include <cstdio>
#include <jpeglib.h>
#include <jerror.h>
// clang-format on

#include <array>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <csetjmp>
#include <cstring>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "hivox/core/error.h"
#include "hivox/io/atomic_file.h"

namespace hivox {

namespace {

/// What is wrong with an image header's size before anything is allocated for it, or "".
std::string header_size_problem(long width, long height) {
  if (width <= kMaxImageSide && height <= kMaxImageSide) return "";
  return fmt::format("its header says {}x{} pixels; at most {} a side are read", width, height,
                     kMaxImageSide);
}

namespace fs = std::filesystem;

enum class FileFormat { Png, Jpeg, Pnm, Unknown };

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using FilePtr = std::unique_ptr<std::FILE, FileCloser>;

FilePtr open_for_reading(const fs::path& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) fail(ErrorCode::Io, "{}: file does not exist", path.string());
  if (fs::is_directory(path, ec))
    fail(ErrorCode::Io, "{}: is a directory, expected an image file", path.string());
  FilePtr f(std::fopen(path.c_str(), "rb"));
  if (!f)
    fail(ErrorCode::Io, "{}: cannot open for reading ({})", path.string(), std::strerror(errno));
  return f;
}

FileFormat sniff(std::FILE* f) {
  std::array<unsigned char, 8> magic{};
  const std::size_t n = std::fread(magic.data(), 1, magic.size(), f);
  std::rewind(f);
  if (n >= 8 && png_sig_cmp(magic.data(), 0, 8) == 0) return FileFormat::Png;
  if (n >= 3 && magic[0] == 0xFF && magic[1] == 0xD8 && magic[2] == 0xFF) return FileFormat::Jpeg;
  if (n >= 2 && magic[0] == 'P' && (magic[1] == '5' || magic[1] == '6')) return FileFormat::Pnm;
  return FileFormat::Unknown;
}

// ---- PNG -------------------------------------------------------------------------------------

struct PngRaw {
  int width = 0, height = 0, bit_depth = 0, channels = 0;
  std::vector<uint8_t> bytes;  // rows, tightly packed, host byte order for 16-bit samples
};

struct PngErrorState {
  std::jmp_buf jump;
  char message[256] = {};
};

void png_error_fn(png_structp png, png_const_charp message) {
  auto* state = static_cast<PngErrorState*>(png_get_error_ptr(png));
  std::snprintf(state->message, sizeof state->message, "%s", message);
  std::longjmp(state->jump, 1);
}
void png_warning_fn(png_structp, png_const_charp) {}

enum class PngMode { Raw16Gray, Rgb8 };

// Plain C-style function: nothing with a destructor lives between setjmp and longjmp.
// Returns an empty string on success, otherwise libpng's reason.
std::string read_png_file(std::FILE* f, PngMode mode, PngRaw* out, std::vector<png_bytep>* rows) {
  PngErrorState state;
  png_structp png =
      png_create_read_struct(PNG_LIBPNG_VER_STRING, &state, png_error_fn, png_warning_fn);
  if (!png) return "out of memory";
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_read_struct(&png, nullptr, nullptr);
    return "out of memory";
  }
  if (setjmp(state.jump)) {
    png_destroy_read_struct(&png, &info, nullptr);
    return state.message[0] ? state.message : "corrupt PNG";
  }
  png_init_io(png, f);
  png_read_info(png, info);
  const int color_type = png_get_color_type(png, info);
  const int bit_depth = png_get_bit_depth(png, info);
  const png_uint_32 png_width = png_get_image_width(png, info);
  const png_uint_32 png_height = png_get_image_height(png, info);
  if (std::string problem = header_size_problem(png_width, png_height); !problem.empty()) {
    png_destroy_read_struct(&png, &info, nullptr);
    return problem;
  }
  out->width = static_cast<int>(png_width);
  out->height = static_cast<int>(png_height);
  if (mode == PngMode::Raw16Gray) {
    // Depth: accept exactly one 16-bit grey channel; report what was found otherwise.
    out->bit_depth = bit_depth;
    out->channels = png_get_channels(png, info);
    if (color_type != PNG_COLOR_TYPE_GRAY || bit_depth != 16) {
      png_destroy_read_struct(&png, &info, nullptr);
      return "";  // caller inspects bit_depth / channels
    }
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
    png_set_swap(png);
#endif
  } else {
    if (color_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
    if (color_type == PNG_COLOR_TYPE_GRAY && bit_depth < 8) png_set_expand_gray_1_2_4_to_8(png);
    if (png_get_valid(png, info, PNG_INFO_tRNS)) png_set_tRNS_to_alpha(png);
    if (bit_depth == 16) png_set_strip_16(png);
    if (color_type == PNG_COLOR_TYPE_GRAY || color_type == PNG_COLOR_TYPE_GRAY_ALPHA)
      png_set_gray_to_rgb(png);
    png_set_strip_alpha(png);
    png_read_update_info(png, info);
    out->bit_depth = 8;
    out->channels = 3;
  }
  const std::size_t row_bytes = png_get_rowbytes(png, info);
  out->bytes.resize(row_bytes * static_cast<std::size_t>(out->height));
  rows->resize(static_cast<std::size_t>(out->height));
  for (int y = 0; y < out->height; ++y) (*rows)[y] = out->bytes.data() + row_bytes * y;
  png_read_image(png, rows->data());
  png_read_end(png, nullptr);
  png_destroy_read_struct(&png, &info, nullptr);
  return "";
}

PngRaw read_png(const fs::path& path, std::FILE* f, PngMode mode) {
  PngRaw raw;
  std::vector<png_bytep> rows;
  const std::string problem = read_png_file(f, mode, &raw, &rows);
  if (!problem.empty())
    fail(ErrorCode::InvalidData, "{}: unreadable PNG ({})", path.string(), problem);
  return raw;
}

// ---- JPEG ------------------------------------------------------------------------------------

struct JpegErrorManager {
  jpeg_error_mgr base;
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX] = {};
};

void jpeg_error_exit(j_common_ptr cinfo) {
  auto* err = reinterpret_cast<JpegErrorManager*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, err->message);
  std::longjmp(err->jump, 1);
}
// libjpeg decodes past damaged data with a warning and fills the rest of the image with grey;
// such a frame is an error here, not a silently wrong image. Stray bytes between markers
// (JWRN_EXTRANEOUS_DATA) are skipped without harm and stay quiet.
void jpeg_warning_is_error(j_common_ptr cinfo, int msg_level) {
  if (msg_level == -1 && cinfo->err->msg_code != JWRN_EXTRANEOUS_DATA)
    (*cinfo->err->error_exit)(cinfo);
}

std::string read_jpeg_file(std::FILE* f, ColorImage* out) {
  jpeg_decompress_struct cinfo;
  JpegErrorManager err;
  cinfo.err = jpeg_std_error(&err.base);
  err.base.error_exit = jpeg_error_exit;
  err.base.emit_message = jpeg_warning_is_error;
  if (setjmp(err.jump)) {
    jpeg_destroy_decompress(&cinfo);
    return err.message[0] ? err.message : "corrupt JPEG";
  }
  jpeg_create_decompress(&cinfo);
  jpeg_stdio_src(&cinfo, f);
  jpeg_read_header(&cinfo, TRUE);
  if (std::string problem = header_size_problem(cinfo.image_width, cinfo.image_height);
      !problem.empty()) {
    jpeg_destroy_decompress(&cinfo);
    return problem;
  }
  cinfo.out_color_space = JCS_RGB;
  jpeg_start_decompress(&cinfo);
  out->resize(static_cast<int>(cinfo.output_width), static_cast<int>(cinfo.output_height));
  while (cinfo.output_scanline < cinfo.output_height) {
    JSAMPROW row = reinterpret_cast<JSAMPROW>(
        out->data() + static_cast<std::size_t>(cinfo.output_scanline) * cinfo.output_width);
    jpeg_read_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_decompress(&cinfo);
  jpeg_destroy_decompress(&cinfo);
  return "";
}

// ---- PNM -------------------------------------------------------------------------------------

struct PnmHeader {
  char kind = 0;  // '5' grey, '6' RGB
  int width = 0, height = 0, maxval = 0;
};

PnmHeader read_pnm_header(const fs::path& path, std::FILE* f) {
  PnmHeader h;
  auto next_token = [&]() -> long {
    int c = std::fgetc(f);
    while (c != EOF) {
      if (c == '#') {
        while (c != EOF && c != '\n') c = std::fgetc(f);
      } else if (!std::isspace(c)) {
        break;
      }
      c = std::fgetc(f);
    }
    if (c == EOF || !std::isdigit(c)) return -1;
    long value = 0;
    while (c != EOF && std::isdigit(c)) {
      value = value * 10 + (c - '0');
      if (value > 1000000) return -1;
      c = std::fgetc(f);
    }
    return value;  // c (one whitespace) consumed, as the format requires
  };
  const int p = std::fgetc(f);
  h.kind = static_cast<char>(std::fgetc(f));
  if (p != 'P' || (h.kind != '5' && h.kind != '6'))
    fail(ErrorCode::InvalidData, "{}: not a binary PGM/PPM file", path.string());
  h.width = static_cast<int>(next_token());
  h.height = static_cast<int>(next_token());
  h.maxval = static_cast<int>(next_token());
  if (h.width <= 0 || h.height <= 0 || h.maxval <= 0 || h.maxval > 65535)
    fail(ErrorCode::InvalidData, "{}: malformed PNM header", path.string());
  if (std::string problem = header_size_problem(h.width, h.height); !problem.empty())
    fail(ErrorCode::InvalidData, "{}: {}", path.string(), problem);
  return h;
}

std::vector<uint8_t> read_exact(const fs::path& path, std::FILE* f, std::size_t bytes) {
  std::vector<uint8_t> data(bytes);
  if (std::fread(data.data(), 1, bytes, f) != bytes)
    fail(ErrorCode::InvalidData, "{}: truncated image data", path.string());
  return data;
}

std::string describe_png(const PngRaw& raw) {
  const char* kind = raw.channels == 1   ? "grey"
                     : raw.channels == 2 ? "grey+alpha"
                     : raw.channels == 3 ? "RGB"
                                         : "RGBA";
  return fmt::format("{}-bit {}", raw.bit_depth, kind);
}

// ---- writing ---------------------------------------------------------------------------------

void append_to_vector(png_structp png, png_bytep data, png_size_t length) {
  auto* out = static_cast<std::vector<uint8_t>*>(png_get_io_ptr(png));
  out->insert(out->end(), data, data + length);
}
void flush_nothing(png_structp) {}

/// Writes the PNG into `f`, or appended to `memory` when `f` is null.
std::string write_png_file(std::FILE* f, int width, int height, int bit_depth, int color_type,
                           const uint8_t* pixels, std::size_t row_bytes,
                           std::vector<png_bytep>* rows, std::vector<uint8_t>* memory = nullptr,
                           int compression_level = 3) {
  PngErrorState state;
  png_structp png =
      png_create_write_struct(PNG_LIBPNG_VER_STRING, &state, png_error_fn, png_warning_fn);
  if (!png) return "out of memory";
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_write_struct(&png, nullptr);
    return "out of memory";
  }
  if (setjmp(state.jump)) {
    png_destroy_write_struct(&png, &info);
    return state.message[0] ? state.message : "libpng write error";
  }
  if (f != nullptr)
    png_init_io(png, f);
  else
    png_set_write_fn(png, memory, append_to_vector, flush_nothing);
  png_set_compression_level(png, compression_level);
  png_set_IHDR(png, info, static_cast<png_uint_32>(width), static_cast<png_uint_32>(height),
               bit_depth, color_type, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
  if (bit_depth == 16) png_set_swap(png);
#endif
  rows->resize(static_cast<std::size_t>(height));
  for (int y = 0; y < height; ++y)
    (*rows)[y] = const_cast<png_bytep>(pixels + row_bytes * static_cast<std::size_t>(y));
  png_write_image(png, rows->data());
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return "";
}

void write_png_any(const fs::path& path, int width, int height, int bit_depth, int color_type,
                   const void* pixels, std::size_t row_bytes) {
  if (width <= 0 || height <= 0)
    fail(ErrorCode::InvalidArgument, "{}: cannot write an empty image", path.string());
  AtomicFile file(path);
  FilePtr f(std::fopen(file.temp_path().c_str(), "wb"));
  if (!f)
    fail(ErrorCode::Io, "{}: cannot open for writing ({})", path.string(), std::strerror(errno));
  std::vector<png_bytep> rows;
  const std::string problem = write_png_file(f.get(), width, height, bit_depth, color_type,
                                             static_cast<const uint8_t*>(pixels), row_bytes, &rows);
  if (!problem.empty()) fail(ErrorCode::Io, "{}: PNG write failed ({})", path.string(), problem);
  if (std::fclose(f.release()) != 0)
    fail(ErrorCode::Io, "{}: write failed ({})", path.string(), std::strerror(errno));
  file.commit();
}

}  // namespace

Image<uint16_t> read_depth16(const fs::path& path) {
  FilePtr f = open_for_reading(path);
  switch (sniff(f.get())) {
    case FileFormat::Png: {
      PngRaw raw = read_png(path, f.get(), PngMode::Raw16Gray);
      if (raw.bit_depth != 16 || raw.channels != 1)
        fail(ErrorCode::InvalidData,
             "{}: depth must be a 16-bit single-channel PNG, found {} (is this a colour image?)",
             path.string(), describe_png(raw));
      Image<uint16_t> image(raw.width, raw.height);
      std::memcpy(image.data(), raw.bytes.data(), image.size() * sizeof(uint16_t));
      return image;
    }
    case FileFormat::Pnm: {
      const PnmHeader h = read_pnm_header(path, f.get());
      if (h.kind != '5' || h.maxval <= 255)
        fail(ErrorCode::InvalidData,
             "{}: depth must be a 16-bit single-channel PGM, found {} with maxval {}",
             path.string(), h.kind == '6' ? "a colour PPM" : "a PGM", h.maxval);
      Image<uint16_t> image(h.width, h.height);
      const auto bytes = read_exact(path, f.get(), image.size() * 2);
      for (std::size_t i = 0; i < image.size(); ++i)  // PNM stores 16-bit samples big-endian
        image.data()[i] = static_cast<uint16_t>((bytes[2 * i] << 8) | bytes[2 * i + 1]);
      return image;
    }
    case FileFormat::Jpeg:
      fail(ErrorCode::InvalidData,
           "{}: depth must be a 16-bit single-channel PNG, found a JPEG (lossy colour image)",
           path.string());
    case FileFormat::Unknown:
      break;
  }
  fail(ErrorCode::InvalidData, "{}: not a PNG or PGM image", path.string());
}

ColorImage read_color(const fs::path& path) {
  FilePtr f = open_for_reading(path);
  switch (sniff(f.get())) {
    case FileFormat::Png: {
      PngRaw raw = read_png(path, f.get(), PngMode::Rgb8);
      ColorImage image(raw.width, raw.height);
      std::memcpy(image.data(), raw.bytes.data(), image.size() * sizeof(Rgb8));
      return image;
    }
    case FileFormat::Jpeg: {
      ColorImage image;
      const std::string problem = read_jpeg_file(f.get(), &image);
      if (!problem.empty())
        fail(ErrorCode::InvalidData, "{}: unreadable JPEG ({})", path.string(), problem);
      return image;
    }
    case FileFormat::Pnm: {
      const PnmHeader h = read_pnm_header(path, f.get());
      const int channels = h.kind == '6' ? 3 : 1;
      const int sample_bytes = h.maxval > 255 ? 2 : 1;
      ColorImage image(h.width, h.height);
      const auto bytes = read_exact(
          path, f.get(), image.size() * static_cast<std::size_t>(channels * sample_bytes));
      auto sample = [&](std::size_t i) -> uint8_t {
        const unsigned v = sample_bytes == 2 ? (bytes[2 * i] << 8 | bytes[2 * i + 1]) : bytes[i];
        return static_cast<uint8_t>(v * 255u / static_cast<unsigned>(h.maxval));
      };
      for (std::size_t i = 0; i < image.size(); ++i) {
        if (channels == 3)
          image.data()[i] = {sample(3 * i), sample(3 * i + 1), sample(3 * i + 2)};
        else
          image.data()[i] = {sample(i), sample(i), sample(i)};
      }
      return image;
    }
    case FileFormat::Unknown:
      break;
  }
  fail(ErrorCode::InvalidData, "{}: not a PNG, JPEG or PNM image", path.string());
}

DepthImage depth_to_metres(const Image<uint16_t>& raw, double depth_scale, uint16_t invalid_raw,
                           double depth_offset_m) {
  if (!(depth_scale > 0) || !std::isfinite(depth_scale))
    fail(ErrorCode::InvalidArgument, "depth_scale must be > 0 (raw units per metre), got {}",
         depth_scale);
  DepthImage depth(raw.width(), raw.height());
  const float inv = static_cast<float>(1.0 / depth_scale);
  const float offset = static_cast<float>(depth_offset_m);
  const uint16_t* in = raw.data();
  float* out = depth.data();
  for (std::size_t i = 0; i < raw.size(); ++i) {
    const uint16_t v = in[i];
    out[i] = (v == 0 || v == invalid_raw) ? 0.0f : static_cast<float>(v) * inv + offset;
  }
  return depth;
}

Image<uint16_t> depth_to_raw(const DepthImage& depth_m, double depth_scale) {
  if (!(depth_scale > 0) || !std::isfinite(depth_scale))
    fail(ErrorCode::InvalidArgument, "depth_scale must be > 0 (raw units per metre), got {}",
         depth_scale);
  Image<uint16_t> raw(depth_m.width(), depth_m.height());
  for (std::size_t i = 0; i < raw.size(); ++i) {
    const float d = depth_m.data()[i];
    if (!(d > 0.0f) || !std::isfinite(d)) continue;
    const double v = std::round(static_cast<double>(d) * depth_scale);
    raw.data()[i] = static_cast<uint16_t>(v < 1.0 ? 1.0 : (v > 65535.0 ? 65535.0 : v));
  }
  return raw;
}

void write_png(const fs::path& path, const Image<uint16_t>& image) {
  write_png_any(path, image.width(), image.height(), 16, PNG_COLOR_TYPE_GRAY, image.data(),
                static_cast<std::size_t>(image.width()) * 2);
}

void write_png(const fs::path& path, const Image<uint8_t>& image) {
  write_png_any(path, image.width(), image.height(), 8, PNG_COLOR_TYPE_GRAY, image.data(),
                static_cast<std::size_t>(image.width()));
}

std::vector<uint8_t> encode_png(const ColorImage& image, int compression_level) {
  if (image.width() <= 0 || image.height() <= 0)
    fail(ErrorCode::InvalidArgument, "cannot encode an empty image as PNG");
  if (compression_level < 0 || compression_level > 9)
    fail(ErrorCode::InvalidArgument, "PNG compression level must be in 0..9, got {}",
         compression_level);
  std::vector<uint8_t> out;
  std::vector<png_bytep> rows;
  const std::string problem =
      write_png_file(nullptr, image.width(), image.height(), 8, PNG_COLOR_TYPE_RGB,
                     reinterpret_cast<const uint8_t*>(image.data()),
                     static_cast<std::size_t>(image.width()) * 3, &rows, &out, compression_level);
  if (!problem.empty()) fail(ErrorCode::Io, "PNG encoding failed ({})", problem);
  return out;
}

void write_png(const fs::path& path, const ColorImage& image) {
  static_assert(sizeof(Rgb8) == 3, "Rgb8 must be tightly packed");
  write_png_any(path, image.width(), image.height(), 8, PNG_COLOR_TYPE_RGB, image.data(),
                static_cast<std::size_t>(image.width()) * 3);
}

}  // namespace hivox

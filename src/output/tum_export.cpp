#include "hivox/output/tum_export.h"

#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "hivox/core/error.h"
#include "hivox/core/log.h"
#include "hivox/io/atomic_file.h"
#include "hivox/io/image_io.h"
#include "hivox/io/intrinsics_io.h"
#include "hivox/io/trajectory_io.h"
#include "hivox/output/output_folder.h"

namespace hivox {

namespace {

namespace fs = std::filesystem;

class TextFile {
 public:
  explicit TextFile(fs::path path)
      : path_(std::move(path)), file_(path_), f_(std::fopen(file_.temp_path().c_str(), "w")) {
    if (!f_) fail(ErrorCode::Io, "{}: cannot open for writing", path_.string());
  }
  void line(const std::string& text) {
    if (std::fputs(text.c_str(), f_.get()) < 0 || std::fputc('\n', f_.get()) == EOF)
      fail(ErrorCode::Io, "{}: write failed", path_.string());
  }
  void close() {
    if (std::fclose(f_.release()) != 0) fail(ErrorCode::Io, "{}: write failed", path_.string());
    file_.commit();
  }

 private:
  struct Closer {
    void operator()(std::FILE* f) const { std::fclose(f); }
  };
  fs::path path_;
  AtomicFile file_;
  std::unique_ptr<std::FILE, Closer> f_;
};

}  // namespace

void export_tum(DatasetReader& reader, const fs::path& out, double depth_scale, std::size_t frames,
                const ExportProgress& progress, bool overwrite) {
  if (!(depth_scale > 0.0) || !std::isfinite(depth_scale))
    fail(ErrorCode::InvalidArgument,
         "export_tum: depth_scale must be > 0 (raw units per metre), got {}", depth_scale);
  OutputFolder folder(out, overwrite);
  const fs::path& dir = folder.dir();
  const DatasetInfo& info = reader.info();
  const std::size_t total = frames == 0 ? reader.size() : std::min(frames, reader.size());
  std::error_code ec;
  fs::create_directories(dir / "depth", ec);
  if (ec)
    fail(ErrorCode::Io, "{}: cannot create directory ({})", (dir / "depth").string(), ec.message());
  if (info.has_color) {
    fs::create_directories(dir / "rgb", ec);
    if (ec)
      fail(ErrorCode::Io, "{}: cannot create directory ({})", (dir / "rgb").string(), ec.message());
  }

  const std::string origin = fmt::format("exported by hivox from {}", info.source);
  TextFile depth_list(dir / "depth.txt");
  depth_list.line("# depth maps");
  depth_list.line("# " + origin);
  depth_list.line("# timestamp filename");
  std::unique_ptr<TextFile> rgb_list, assoc_list;
  if (info.has_color) {
    rgb_list = std::make_unique<TextFile>(dir / "rgb.txt");
    rgb_list->line("# color images");
    rgb_list->line("# " + origin);
    rgb_list->line("# timestamp filename");
    assoc_list = std::make_unique<TextFile>(dir / "associations.txt");
    assoc_list->line("# " + origin);
    assoc_list->line("# timestamp_rgb rgb_file timestamp_depth depth_file");
  }

  const double max_depth_m = 65535.0 / depth_scale;
  std::size_t clipped = 0;
  std::vector<StampedPose> poses;
  for (std::size_t i = 0; i < total; ++i) {
    RgbdFrame frame = reader.read(i);
    const std::string stamp = fmt::format("{:.6f}", frame.timestamp_s);
    for (std::size_t k = 0; k < frame.depth_m.size(); ++k) {
      float& d = frame.depth_m.data()[k];
      if (d > max_depth_m) {
        d = 0.0f;
        ++clipped;
      }
    }
    const std::string depth_file = "depth/" + stamp + ".png";
    write_png(dir / depth_file, depth_to_raw(frame.depth_m, depth_scale));
    depth_list.line(stamp + " " + depth_file);
    if (info.has_color && !frame.color.empty()) {
      const std::string rgb_file = "rgb/" + stamp + ".png";
      write_png(dir / rgb_file, frame.color);
      rgb_list->line(stamp + " " + rgb_file);
      assoc_list->line(stamp + " " + rgb_file + " " + stamp + " " + depth_file);
    }
    if (frame.T_wc_gt) poses.push_back({frame.timestamp_s, *frame.T_wc_gt});
    if (progress) progress(i + 1, total);
  }
  depth_list.close();
  if (rgb_list) rgb_list->close();
  if (assoc_list) assoc_list->close();
  if (!poses.empty()) write_tum_trajectory(dir / "groundtruth.txt", poses, origin);

  IntrinsicsFile intrinsics;
  intrinsics.camera = info.rig.depth_camera;
  intrinsics.depth_scale = depth_scale;
  intrinsics.depth_noise = info.rig.depth_noise;  // so that a rendered, noise-free set reads so
  intrinsics.note = origin;
  write_intrinsics_json(dir / "intrinsics.json", intrinsics);
  folder.commit();
  if (clipped > 0)
    log::warn(
        "export_tum: {} depth pixels beyond {:.2f} m (the 16-bit limit at depth_scale {}) "
        "were written as invalid",
        clipped, max_depth_m, depth_scale);
}

}  // namespace hivox

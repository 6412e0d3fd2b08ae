// Microsoft 7-Scenes layout: seq-NN/frame-NNNNNN.{color.png,depth.png,pose.txt}.

#include <algorithm>
#include <cctype>
#include <unordered_set>

#include <fmt/format.h>

#include "hivox/core/error.h"
#include "io/dataset_internal.h"

namespace hivox::detail {

namespace fs = std::filesystem;

namespace {

constexpr uint16_t kInvalidDepth = 65535;

struct SequenceFrame {
  long number = 0;
  std::string stem;  // frame-NNNNNN
};

}  // namespace

std::unique_ptr<FileDataset> open_seven_scenes(const fs::path& dir, const DatasetParams& params) {
  const std::vector<fs::path> sequences = seven_scenes_sequences(dir);
  if (sequences.empty())
    fail(ErrorCode::InvalidData, "{}: no seq-NN/frame-NNNNNN.depth.png files", dir.string());

  std::vector<FrameFiles> frames;
  bool any_color = false;
  for (const fs::path& seq : sequences) {
    std::unordered_set<std::string> names;
    std::vector<SequenceFrame> depth_frames;
    std::error_code ec;
    for (fs::directory_iterator it(seq, ec), end; !ec && it != end; it.increment(ec)) {
      std::string name = it->path().filename().string();
      if (name.starts_with("frame-") && name.ends_with(".depth.png")) {
        const std::string stem =
            name.substr(0, name.size() - std::string_view(".depth.png").size());
        const std::string digits = stem.substr(6);
        if (!digits.empty() && digits.size() <= 9 &&
            std::all_of(digits.begin(), digits.end(),
                        [](char c) { return std::isdigit(static_cast<unsigned char>(c)); }))
          depth_frames.push_back({std::stol(digits), stem});
      }
      names.insert(std::move(name));
    }
    if (ec) fail(ErrorCode::Io, "{}: cannot list the folder ({})", seq.string(), ec.message());
    std::sort(depth_frames.begin(), depth_frames.end(),
              [](const SequenceFrame& a, const SequenceFrame& b) { return a.number < b.number; });
    for (const SequenceFrame& s : depth_frames) {
      FrameFiles f;
      f.depth = seq / (s.stem + ".depth.png");
      // Colour paths are set for every frame once any exists, so that a missing one is an
      // error naming the file rather than a silently colourless frame.
      f.color = seq / (s.stem + ".color.png");
      any_color = any_color || names.contains(s.stem + ".color.png");
      if (names.contains(s.stem + ".pose.txt")) f.pose_file = seq / (s.stem + ".pose.txt");
      // Timestamps keep increasing across sequences: frame index / 30 Hz.
      f.timestamp_s = static_cast<double>(frames.size()) / kFrameRateHz;
      frames.push_back(std::move(f));
    }
  }
  if (!any_color)
    for (FrameFiles& f : frames) f.color.clear();

  const Calibration calibration = resolve_calibration(dir, params,
                                                      {.layout_name = "7-Scenes",
                                                       .preset = &camera_preset("seven_scenes"),
                                                       .guess_from_folder_name = false,
                                                       .depth_scale = 0,
                                                       .depth_scale_source = ""});
  DatasetInfo info;
  info.source = dir.string();
  info.layout = DatasetLayout::SevenScenes;
  calibration.apply_to(info, params.undistort);
  if (any_color)
    info.warnings.push_back(
        "7-Scenes colour and depth come from two cameras and are not registered; hivox treats "
        "them as registered, so colours on surfaces are off by a few pixels");
  return std::make_unique<FileDataset>(std::move(info), std::move(frames),
                                       DepthDecoding{calibration.depth_scale, kInvalidDepth, 0.0});
}

}  // namespace hivox::detail

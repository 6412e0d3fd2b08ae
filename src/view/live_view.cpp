#include "hivox/view/live_view.h"

#include <algorithm>
#include <cmath>
#include <mutex>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "hivox/core/error.h"
#include "hivox/core/timer.h"
#include "hivox/io/image_io.h"
#include "hivox/raycast/raycaster.h"
#include "hivox/raycast/render.h"
#include "hivox/track/params.h"
#include "view/assets.h"
#include "view/json_util.h"

namespace hivox {

using json = nlohmann::json;

void LiveViewParams::validate() const {
  server.validate();
  if (!(render_hz >= 0.0 && render_hz <= 120.0))
    fail(ErrorCode::InvalidArgument, "live view render rate must be in 0..120 Hz, got {}",
         render_hz);
  if (render_width_px < 16 || render_width_px > 4096)
    fail(ErrorCode::InvalidArgument, "live view render width must be in 16..4096 px, got {}",
         render_width_px);
}

std::string_view to_string(LiveState state) {
  switch (state) {
    case LiveState::Starting:
      return "starting";
    case LiveState::Running:
      return "running";
    case LiveState::Finished:
      return "finished";
    case LiveState::Stopped:
      return "stopped";
    case LiveState::Failed:
      return "failed";
  }
  return "unknown";
}

namespace {

/// One frame as the page plots it: its statistics and where the camera was.
struct FrameSample {
  FrameStats stats;
  Vec3f position_w;
};

/// The renders of one moment, handed from the run's thread to the server's as a whole; each
/// PNG is encoded once, on the first request for it.
/// The pictures of a snapshot, in the order of their names in the routes.
enum class Picture { Shaded, Color, Normals, Levels, Depth, Count };
constexpr std::array<std::string_view, static_cast<std::size_t>(Picture::Count)> kPictureNames = {
    "shaded", "color", "normals", "levels", "depth"};

struct Snapshot {
  static constexpr std::size_t kCount = static_cast<std::size_t>(Picture::Count);
  int64_t version = 0;
  std::size_t frame = 0;
  float depth_min_m = 0, depth_max_m = 0;  ///< the depth image's colour scale
  std::array<ColorImage, kCount> images;
  std::array<std::once_flag, kCount> encoded_once;
  std::array<std::string, kCount> png;

  ColorImage& image(Picture p) { return images[static_cast<std::size_t>(p)]; }
  const std::string& encoded(Picture p) {
    const auto k = static_cast<std::size_t>(p);
    std::call_once(encoded_once[k], [&] {
      const std::vector<uint8_t> bytes = encode_png(images[k]);
      png[k].assign(bytes.begin(), bytes.end());
    });
    return png[k];
  }
};

}  // namespace

struct LiveView::State {
  mutable std::mutex mutex;  ///< guards everything below (held for copies and appends only)
  std::string source, settings;
  std::size_t frames_total = 0;
  int levels = 1;
  float voxel_size_m = 0;
  bool tracking = false;
  LiveState state = LiveState::Starting;
  std::string message;
  std::vector<FrameSample> samples;
  TrackingCounts counts;
  int64_t blocks_total = 0, peak_blocks = 0, dropped_blocks = 0, memory_bytes = 0;
  std::shared_ptr<Snapshot> snapshot;
  Stopwatch clock;  ///< since start()
  // The run's thread only:
  Stopwatch since_render;
  bool rendered = false;
  double loop_ms = 0;
  int64_t renders = 0;

  /// Renders the model from `T_wc` into a new snapshot. The per-frame raycast the reconstruction
  /// made for tracking is from that pose already (when `reuse`), so only its pictures are made;
  /// else the model is raycast at `width_px`.
  void render(const Reconstruction& rec, const Pose& T_wc, const DepthImage* depth,
              std::size_t frame, int width_px, bool reuse) {
    const RaycastResult* cast = &rec.last_raycast();
    RaycastResult view;
    if (!reuse || cast->depth_m.empty() || !cast->T_wc.isApprox(T_wc)) {
      const PinholeCamera& full = rec.rig().depth_camera;
      const PinholeCamera camera =
          full.scaled(static_cast<float>(width_px) / static_cast<float>(full.width));
      view = rec.render(camera, T_wc);  // on the device the frames run on
      cast = &view;
    }
    const RaycastResult& r = *cast;
    auto snap = std::make_shared<Snapshot>();
    snap->frame = frame;
    snap->image(Picture::Shaded) = render_shaded(r);
    snap->image(Picture::Color) = render_colors(r);
    snap->image(Picture::Normals) = render_normals(r);
    snap->image(Picture::Levels) = render_levels(r);
    if (depth != nullptr && !depth->empty()) {
      const DepthExtent extent = depth_extent(*depth);
      snap->depth_min_m = extent.min_m;
      snap->depth_max_m = extent.max_m;
      // At most the renders' width: the page shows it beside them.
      const int step = std::max(1, depth->width() / std::max(width_px, 1));
      DepthImage small(depth->width() / step, depth->height() / step);
      for (int y = 0; y < small.height(); ++y)
        for (int x = 0; x < small.width(); ++x) small(x, y) = (*depth)(x * step, y * step);
      snap->image(Picture::Depth) = render_depth(small, extent.min_m, extent.max_m);
    } else {
      const DepthExtent extent = depth_extent(r.depth_m);
      snap->depth_min_m = extent.min_m;
      snap->depth_max_m = extent.max_m;
      snap->image(Picture::Depth) = render_depth(r.depth_m, extent.min_m, extent.max_m);
    }
    ++renders;
    since_render.restart();
    rendered = true;
    const std::lock_guard lock(mutex);
    snap->version = snapshot ? snapshot->version + 1 : 1;
    snapshot = std::move(snap);
  }

  json status_json() const {
    const std::lock_guard lock(mutex);
    json j;
    j["source"] = source;
    j["settings"] = settings;
    j["state"] = to_string(state);
    j["message"] = message;
    j["frames_total"] = frames_total;
    j["frames_done"] = samples.size();
    j["elapsed_s"] = clock.elapsed_ms() / 1e3;
    j["levels"] = levels;
    json sizes = json::array(), colors = json::array();
    for (int l = 0; l < levels; ++l) {
      sizes.push_back(voxel_size_m * static_cast<float>(1 << l) * 1e3f);
      colors.push_back(view::hex_color(level_color(l)));
    }
    j["voxel_sizes_mm"] = sizes;
    j["level_colors"] = colors;
    j["tracking"] = tracking;
    j["tracking_counts"] = {{"good", counts.good}, {"poor", counts.poor}, {"lost", counts.lost}};
    j["blocks_total"] = blocks_total;
    j["peak_blocks"] = peak_blocks;
    j["dropped_blocks"] = dropped_blocks;
    j["memory_bytes"] = memory_bytes;
    j["render_version"] = snapshot ? snapshot->version : 0;
    j["render_frame"] = snapshot ? snapshot->frame : 0;
    j["depth_range_m"] = {snapshot ? snapshot->depth_min_m : 0.0f,
                          snapshot ? snapshot->depth_max_m : 0.0f};
    return j;
  }

  json frames_json(std::size_t from) const {
    std::vector<FrameSample> copy;
    {
      const std::lock_guard lock(mutex);
      if (from < samples.size())
        copy.assign(samples.begin() + static_cast<std::ptrdiff_t>(from), samples.end());
    }
    json list = json::array();
    for (const FrameSample& sample : copy) {
      const FrameStats& s = sample.stats;
      list.push_back({{"i", s.index},
                      {"t", s.timestamp_s},
                      {"ms",
                       {{"read", s.read_ms},
                        {"track", s.track_ms},
                        {"allocate", s.allocate_ms},
                        {"integrate", s.integrate_ms},
                        {"refine", s.refine_ms},
                        {"raycast", s.raycast_ms},
                        {"total", s.total_ms}}},
                      {"blocks", s.blocks_per_level},
                      {"dropped", s.dropped_blocks},
                      {"tracking", to_string(s.tracking)},
                      {"fused", s.fused},
                      {"p", {sample.position_w.x, sample.position_w.y, sample.position_w.z}}});
    }
    return json{{"from", from}, {"frames", list}};
  }
};

LiveView::LiveView(const LiveViewParams& params)
    : params_(params), state_(std::make_unique<State>()), server_(params.server) {
  params_.validate();
  State& st = *state_;
  server_.route("/", [](const HttpQuery&) {
    return HttpReply{200, "text/html; charset=utf-8",
                     std::string(*view::static_asset("live.html"))};
  });
  server_.route("/api/status.json",
                [&st](const HttpQuery&) { return HttpReply::json(st.status_json().dump()); });
  server_.route("/api/frames.json", [&st](const HttpQuery& q) {
    const std::size_t from = view::parse_count(q.param("from", "0"), "from");
    return HttpReply::json(st.frames_json(from).dump());
  });
  for (std::size_t k = 0; k < kPictureNames.size(); ++k) {
    const auto picture = static_cast<Picture>(k);
    server_.route(fmt::format("/api/render/{}.png", kPictureNames[k]),
                  [&st, picture](const HttpQuery&) {
                    std::shared_ptr<Snapshot> snap;
                    {
                      const std::lock_guard lock(st.mutex);
                      snap = st.snapshot;
                    }
                    if (!snap || snap->image(picture).empty())
                      return HttpReply::error(404, "no render yet");
                    return HttpReply{200, "image/png", snap->encoded(picture)};
                  });
  }
  server_.start();
}

LiveView::~LiveView() {
  server_.stop();
}

void LiveView::start(std::string_view source, const Reconstruction& rec, std::size_t frames_total) {
  State& st = *state_;
  const std::lock_guard lock(st.mutex);
  st.source = source;
  st.settings = rec.describe();
  st.frames_total = frames_total;
  st.levels = rec.params().map.levels;
  st.voxel_size_m = rec.params().map.voxel_size_m;
  st.state = LiveState::Running;
  st.clock.restart();
}

void LiveView::frame(std::size_t i, const FrameStats& s, const Reconstruction& rec,
                     const RgbdFrame& frame) {
  State& st = *state_;
  Stopwatch watch;
  const Pose& T_wc = rec.trajectory().back().T_wc;
  FrameSample sample{s, {}};
  const Eigen::Vector3d t = T_wc.translation();
  sample.position_w = {static_cast<float>(t.x()), static_cast<float>(t.y()),
                       static_cast<float>(t.z())};
  {
    const std::lock_guard lock(st.mutex);
    st.samples.push_back(std::move(sample));
    st.tracking = s.track_iterations > 0 || st.tracking;
    st.counts = rec.tracking_counts();
    st.blocks_total = s.blocks_total;
    st.peak_blocks = rec.peak_blocks();
    st.dropped_blocks = rec.dropped_blocks();
    st.memory_bytes = rec.map_memory_bytes();
  }
  if (params_.render_hz > 0.0 &&
      (!st.rendered || st.since_render.elapsed_ms() >= 1e3 / params_.render_hz))
    st.render(rec, T_wc, &frame.depth_m, i, params_.render_width_px, true);
  st.loop_ms += watch.elapsed_ms();
}

void LiveView::finish(const Reconstruction& rec, LiveState state, std::string_view message) {
  State& st = *state_;
  if (!rec.trajectory().empty())
    st.render(rec, rec.trajectory().back().T_wc, nullptr,
              rec.frame_stats().empty() ? 0 : rec.frame_stats().back().index,
              params_.render_width_px, false);
  const std::lock_guard lock(st.mutex);
  st.state = state;
  st.message = message;
}

double LiveView::frame_loop_ms() const {
  return state_->loop_ms;
}
int64_t LiveView::renders() const {
  return state_->renders;
}

}  // namespace hivox

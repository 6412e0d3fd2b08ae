#pragma once
/// @file
/// The live view of a run (`hivox reconstruct --view`): a page served while the frames go
/// through, showing the model's raycast from the current pose (shaded, colour, normals or
/// refinement level), the depth frame just fused, the trajectory from above, blocks per level
/// and stage times over the frames, tracking verdicts and the progress.
///
/// The run's thread only records: a frame's statistics (appended under a lock held for the
/// append) and, at most `render_hz` times a second, pictures of the model (from the raycast the
/// reconstruction made for tracking from this pose, or a small raycast of its own when there is
/// none) and of the depth frame, handed over as a finished snapshot. The server's threads turn
/// snapshots into PNGs and JSON on request; a slow or stuck client never holds up a frame.
///
/// The page's data, for scripts: `/api/status.json` (the run, its settings, progress, state),
/// `/api/frames.json?from=N` (the frames' statistics from N on), `/api/render/KIND.png` with KIND
/// shaded, color, normals, levels or depth (the latest snapshot; `render_version` in the status
/// says when it changed).

#include <cstddef>
#include <memory>
#include <string>
#include <string_view>

#include "hivox/core/dataset.h"
#include "hivox/pipeline/reconstruction.h"
#include "hivox/view/server.h"

namespace hivox {

struct LiveViewParams {
  ViewServerParams server;
  double render_hz = 4.0;  ///< model renders per second at most (0 = none)
  /// The width of the view's own raycasts (the depth camera scaled to it) and at most of the
  /// depth picture; the per-frame raycast is shown at the tracking model's resolution.
  int render_width_px = 320;

  /// Throws `Error(InvalidArgument)` naming the bad setting.
  void validate() const;
};

/// How a run being watched ended (the page says so).
enum class LiveState { Starting, Running, Finished, Stopped, Failed };
std::string_view to_string(LiveState state);

class LiveView {
 public:
  /// Starts serving (throws `Error(Io)` when it cannot listen where asked).
  explicit LiveView(const LiveViewParams& params);
  ~LiveView();
  LiveView(const LiveView&) = delete;
  LiveView& operator=(const LiveView&) = delete;

  std::string url() const { return server_.url(); }
  ViewServer& server() { return server_; }

  /// Before the first frame: the dataset's name, the reconstruction (settings, levels) and the
  /// frames to come.
  void start(std::string_view source, const Reconstruction& rec, std::size_t frames_total);
  /// After each processed frame, on the run's thread.
  void frame(std::size_t i, const FrameStats& stats, const Reconstruction& rec,
             const RgbdFrame& frame);
  /// When the run has ended: a last render from the final pose, the state and a message for the
  /// page (e.g. where the results are).
  void finish(const Reconstruction& rec, LiveState state, std::string_view message);

  /// The time the run's thread spent on the view (renders, copies), milliseconds, and the
  /// number of renders made.
  double frame_loop_ms() const;
  int64_t renders() const;

 private:
  struct State;
  LiveViewParams params_;
  std::unique_ptr<State> state_;
  ViewServer server_;
};

}  // namespace hivox

// The live view during a real run: clients polling while frames go through see the frames as
// they come, renders that match the run's own raycast, the end of the run; the run's results are
// the same with and without the view; the view stops with a client still polling.

#include "hivox/view/live_view.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <fstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "hivox/io/image_io.h"
#include "hivox/mesh/extract_mesh.h"
#include "hivox/raycast/render.h"
#include "hivox/run/runner.h"
#include "hivox/synth/synthetic_dataset.h"
#include "run/small_run.h"
#include "test_util.h"
#include "view/http_client.h"

namespace hivox {
namespace {

using json = nlohmann::json;

RunParams small_run() {
  RunParams p = test::small_run();
  p.max_frames = 30;
  return p;
}

SyntheticDataset desk() {
  return test::small_desk(300);
}

ColorImage decode(const std::string& png) {
  test::TempDir dir;
  std::ofstream(dir / "x.png", std::ios::binary) << png;
  return read_color(dir / "x.png");
}

TEST(LiveView, ClientsSeeTheRunAsItGoesAndTheRunIsUnchanged) {
  SyntheticDataset plain_data = desk();
  const RunResult plain = run_reconstruction(plain_data, small_run());

  SyntheticDataset data = desk();
  LiveViewParams lp;
  lp.render_hz = 100;
  LiveView live(lp);
  const int port = live.server().port();
  std::atomic<bool> done{false};
  std::atomic<int> polls{0}, bad{0};
  std::size_t last_seen = 0;
  bool frames_grew = true;
  // A client polls like the page while the frames go through.
  std::thread client([&] {
    while (!done) {
      const auto status = test::get(port, "/api/status.json");
      const auto frames = test::get(port, "/api/frames.json?from=0");
      const auto render = test::get(port, "/api/render/levels.png");
      if (status.status != 200 || frames.status != 200) ++bad;
      const std::size_t n = json::parse(frames.body)["frames"].size();
      frames_grew = frames_grew && n >= last_seen;
      last_seen = n;
      ++polls;
    }
  });
  RunCallbacks callbacks;
  callbacks.on_start = [&](const Reconstruction& rec, std::size_t total) {
    live.start("synthetic desk", rec, total);
  };
  callbacks.on_frame = [&](std::size_t i, const FrameStats& s, const Reconstruction& rec,
                           const RgbdFrame& frame) {
    // Frame 5 comes more than 1/100 s after the last render: it is rendered.
    if (i == 5) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    live.frame(i, s, rec, frame);
    if (i == 5) {
      EXPECT_EQ(json::parse(test::get(port, "/api/status.json").body)["render_frame"], 5);
      // Mid-run: what the page reads agrees with the run.
      const json status = json::parse(test::get(port, "/api/status.json").body);
      EXPECT_EQ(status["state"], "running");
      EXPECT_EQ(status["frames_done"], 6);
      EXPECT_EQ(status["frames_total"], 30);
      EXPECT_EQ(status["levels"], 2);
      EXPECT_EQ(status["blocks_total"], s.blocks_total);
      const json later = json::parse(test::get(port, "/api/frames.json?from=4").body);
      ASSERT_EQ(later["frames"].size(), 2u);
      EXPECT_EQ(later["frames"][1]["i"], 5);
      EXPECT_EQ(later["frames"][1]["blocks"], json(s.blocks_per_level));
      // The levels picture is the run's own per-frame raycast, shown as is.
      const auto png = test::get(port, "/api/render/levels.png");
      EXPECT_EQ(png.status, 200);
      EXPECT_EQ(png.header("Content-Type"), "image/png");
      const ColorImage served = decode(png.body);
      const ColorImage expected = render_levels(rec.last_raycast());
      ASSERT_EQ(served.width(), expected.width());
      ASSERT_EQ(served.height(), expected.height());
      EXPECT_TRUE(std::equal(served.data(), served.data() + served.size(), expected.data()));
      const ColorImage depth = decode(test::get(port, "/api/render/depth.png").body);
      EXPECT_EQ(depth.width(), 160);  // the depth frame at no more than 320 px
    }
  };
  const RunResult watched = run_reconstruction(data, small_run(), callbacks);
  live.finish(*watched.reconstruction, LiveState::Finished, "done");
  done = true;
  client.join();
  EXPECT_GT(polls.load(), 0);
  EXPECT_EQ(bad.load(), 0);
  EXPECT_TRUE(frames_grew);
  const json status = json::parse(test::get(port, "/api/status.json").body);
  EXPECT_EQ(status["state"], "finished");
  EXPECT_EQ(status["message"], "done");
  EXPECT_EQ(status["frames_done"], 30);
  EXPECT_GT(live.renders(), 1);
  EXPECT_EQ(test::get(port, "/api/frames.json?from=x").status, 400);
  EXPECT_EQ(json::parse(test::get(port, "/api/frames.json?from=99").body)["frames"].size(), 0u);
  // Watching changes nothing in the result.
  ASSERT_EQ(plain.reconstruction->trajectory().size(), watched.reconstruction->trajectory().size());
  for (std::size_t i = 0; i < plain.reconstruction->trajectory().size(); ++i)
    EXPECT_TRUE(plain.reconstruction->trajectory()[i].T_wc.isApprox(
        watched.reconstruction->trajectory()[i].T_wc, 0.0));
  EXPECT_EQ(plain.reconstruction->map().blocks_per_level(),
            watched.reconstruction->map().blocks_per_level());
}

TEST(LiveView, EndsWithAClientStillPolling) {
  SyntheticDataset data = desk();
  std::atomic<bool> stop{false};
  std::thread client;
  {
    LiveView live(LiveViewParams{});
    const int port = live.server().port();
    client = std::thread([&, port] {
      while (!stop) (void)test::get(port, "/api/render/shaded.png");
    });
    RunParams p = small_run();
    p.max_frames = 5;
    RunCallbacks callbacks;
    callbacks.on_frame = [&](std::size_t i, const FrameStats& s, const Reconstruction& rec,
                             const RgbdFrame& frame) { live.frame(i, s, rec, frame); };
    const RunResult run = run_reconstruction(data, p, callbacks);
    live.finish(*run.reconstruction, LiveState::Finished, "");
  }  // the view ends here, the client still asking
  stop = true;
  client.join();
  SUCCEED();
}

TEST(LiveView, RefusesBadSettings) {
  LiveViewParams p;
  p.render_hz = -1;
  EXPECT_THROW(LiveView{p}, Error);
  p = {};
  p.render_width_px = 2;
  EXPECT_THROW(LiveView{p}, Error);
}

}  // namespace
}  // namespace hivox

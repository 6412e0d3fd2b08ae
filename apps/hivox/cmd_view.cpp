// `hivox view PATH`: serves the interactive viewer of a run's output folder, a mesh or a saved
// map until interrupted (or for --seconds).

#include <unistd.h>

#include <csignal>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "commands.h"
#include "hivox/core/timer.h"
#include "hivox/view/viewer.h"

namespace hivox::cli {

namespace {

struct ViewOptions {
  std::string path;
  std::string address = "127.0.0.1:0";
  ViewerParams viewer;
  double seconds = 0;
};

volatile std::sig_atomic_t g_view_stop = 0;
extern "C" void stop_viewing(int) {
  g_view_stop = 1;
}

void run_view(const ViewOptions& o) {
  Stopwatch load;
  auto content = std::make_shared<ViewerContent>(load_viewer_content(o.path, o.viewer));
  const double load_s = load.elapsed_ms() / 1e3;
  ViewServer server(ViewServerParams::parse(o.address));
  serve_viewer(server, content);
  server.start();
  fmt::print("{}: {} vertices, {} triangles{} (loaded in {:.2f} s)\n", o.path,
             content->mesh.vertex_count(), content->mesh.triangle_count(),
             content->source_triangles > content->mesh.triangle_count()
                 ? fmt::format(", decimated for display from {}", content->source_triangles)
                 : "",
             load_s);
  fmt::print("viewer: {}  (Ctrl-C ends it)\n", server.url());
  std::fflush(stdout);
  g_view_stop = 0;
  auto previous_int = std::signal(SIGINT, stop_viewing);
  auto previous_term = std::signal(SIGTERM, stop_viewing);
  Stopwatch served;
  while (g_view_stop == 0 && (o.seconds <= 0 || served.elapsed_ms() < o.seconds * 1e3))
    usleep(50'000);
  std::signal(SIGINT, previous_int);
  std::signal(SIGTERM, previous_term);
  server.stop();
  fmt::print("viewer: served {} requests\n", server.requests());
}

}  // namespace

void add_view_command(CLI::App& app) {
  auto options = std::make_shared<ViewOptions>();
  CLI::App* cmd = app.add_subcommand(
      "view",
      "Look at a result in the browser: serves an interactive 3D viewer (orbit, zoom, pan; colour "
      "by fused colour, refinement level or normal; the camera trajectory; the level legend and "
      "the run's statistics) of a run's output folder, a mesh (.ply, .off) or a map file (.hvx), "
      "until Ctrl-C.");
  cmd->add_option("PATH", options->path, "a run's output folder, a mesh or a map file")->required();
  cmd->add_option("--address", options->address,
                  "where to listen: PORT, ADDRESS or ADDRESS:PORT (port 0 = a free one; 0.0.0.0 "
                  "serves other machines too)")
      ->capture_default_str();
  cmd->add_option("--max-triangles", options->viewer.max_triangles,
                  "meshes with more triangles are decimated for display to about this many")
      ->capture_default_str();
  cmd->add_option("--min-weight", options->viewer.min_weight,
                  "meshing a map file: voxels observed fewer times do not make surface")
      ->capture_default_str();
  cmd->add_option("--seconds", options->seconds, "stop after this many seconds (0 = until Ctrl-C)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->footer(
      "Examples:\n"
      "  hivox view out/demo\n"
      "  hivox view rpy.hvx --address 8080\n"
      "  hivox view scan.ply --address 0.0.0.0:8080\n");
  cmd->callback([options] { run_view(*options); });
}

}  // namespace hivox::cli

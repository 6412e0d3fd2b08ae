#include <exception>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "commands.h"
#include "config_file.h"
#include "hivox/core/error.h"
#include "hivox/core/log.h"
#include "hivox/core/version.h"

int main(int argc, char** argv) {
  CLI::App app{
      "hivox: dense 3D reconstruction from RGB-D images with hierarchical voxel block hashing"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string(hivox::library_version()));
  hivox::cli::add_info_command(app);
  hivox::cli::add_devices_command(app);
  hivox::cli::add_reconstruct_command(app);
  hivox::cli::add_demo_command(app);
  hivox::cli::add_synth_command(app);
  hivox::cli::add_eval_command(app);
  hivox::cli::add_map_commands(app);
  hivox::cli::add_view_command(app);
  hivox::cli::add_experiment_command(app);
  try {
    // Settings of a --config file become arguments before the command line's own.
    std::vector<std::string> args = hivox::cli::expand_config_args({argv, argv + argc}, app);
    std::vector<char*> expanded;
    for (std::string& a : args) expanded.push_back(a.data());
    app.parse(static_cast<int>(expanded.size()), expanded.data());
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const hivox::cli::ExitStatus& status) {
    return status.code;
  } catch (const hivox::Error& e) {
    hivox::log::error("{}", e.what());
    return 1;
  } catch (const std::exception& e) {  // a bug or the system (e.g. out of memory), not bad input
    hivox::log::error("unexpected failure: {}", e.what());
    return 1;
  }
  return 0;
}

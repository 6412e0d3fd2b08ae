#include <exception>
#include <string>

#include <CLI/CLI.hpp>

#include "commands.h"
#include "hivox/core/error.h"
#include "hivox/core/log.h"
#include "hivox/core/version.h"

int main(int argc, char** argv) {
  CLI::App app{
      "hivox: dense 3D reconstruction from RGB-D images with hierarchical voxel block hashing"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string(hivox::library_version()));
  hivox::cli::add_info_command(app);
  hivox::cli::add_reconstruct_command(app);
  hivox::cli::add_demo_command(app);
  hivox::cli::add_synth_command(app);
  hivox::cli::add_eval_command(app);
  hivox::cli::add_map_commands(app);
  try {
    app.parse(argc, argv);
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

#pragma once
// Each subcommand of the `hivox` program lives in its own cmd_*.cpp and registers itself here.
// Commands are thin: they parse options, call the library and print.

#include <CLI/CLI.hpp>

namespace hivox::cli {

// (commands are added here as they are implemented)

}  // namespace hivox::cli

#pragma once
// Each subcommand of the `hivox` program lives in its own cmd_*.cpp and registers itself here.
// Commands are thin: they parse options, call the library and print.

#include <CLI/CLI.hpp>

namespace hivox::cli {

/// `hivox info DATASET`: what hivox finds in a dataset folder (cmd_info.cpp).
void add_info_command(CLI::App& app);

/// `hivox reconstruct DATASET`: fuse a sequence, write mesh, trajectory, stats, renders
/// (cmd_reconstruct.cpp).
void add_reconstruct_command(CLI::App& app);

/// `hivox demo`: `reconstruct` on a built-in synthetic scene (cmd_reconstruct.cpp).
void add_demo_command(CLI::App& app);

/// `hivox synth`: renders a built-in synthetic scene and writes it as a TUM RGB-D sequence.
void add_synth_command(CLI::App& app);

/// `hivox eval ate --gt FILE --est FILE`: trajectory accuracy against ground truth (cmd_eval.cpp).
void add_eval_command(CLI::App& app);

}  // namespace hivox::cli

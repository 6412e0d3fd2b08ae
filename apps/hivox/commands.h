#pragma once
// Each subcommand of the `hivox` program lives in its own cmd_*.cpp and registers itself here.
// Commands are thin: they parse options, call the library and print.

#include <string>

#include <CLI/CLI.hpp>

namespace hivox::cli {

/// Exit statuses of `hivox` beyond 0 (success), 1 (an error: bad input, a file that cannot be
/// read or written) and CLI11's own for command-line mistakes; 128 + the signal number when an
/// interrupt stopped a run (its results so far written). README, "Exit status".
inline constexpr int kExitUnusable = 3;  ///< a run finished, but its result is of no use
inline constexpr int kExitBadFrame = 4;  ///< a run stopped at a frame it could not read

/// Thrown by a command to end the program with `code` (after it printed why).
struct ExitStatus {
  int code = 1;
};

/// `hivox info DATASET`: what hivox finds in a dataset folder (cmd_info.cpp).
void add_info_command(CLI::App& app);
/// `hivox devices`: the devices runs can use, the CPU and CUDA's (cmd_info.cpp).
void add_devices_command(CLI::App& app);

/// `hivox reconstruct DATASET`: fuse a sequence, write mesh, trajectory, stats, renders
/// (cmd_reconstruct.cpp).
void add_reconstruct_command(CLI::App& app);

/// `hivox demo`: `reconstruct` on a built-in synthetic scene (cmd_reconstruct.cpp).
void add_demo_command(CLI::App& app);

/// `hivox synth`: renders a built-in synthetic scene and writes it as a TUM RGB-D sequence.
void add_synth_command(CLI::App& app);

/// `hivox mesh`, `hivox render`, `hivox export` on saved maps (cmd_map.cpp).
void add_map_commands(CLI::App& app);
/// `hivox info FILE` for a map file: prints what it holds and returns true; false when `path` is
/// not a map file (cmd_map.cpp).
bool print_map_file_info(const std::string& path);
/// `hivox view PATH`: the interactive viewer of a run's folder, a mesh or a map (cmd_view.cpp).
void add_view_command(CLI::App& app);
/// `hivox eval ate --gt FILE --est FILE`: trajectory accuracy against ground truth (cmd_eval.cpp).
void add_eval_command(CLI::App& app);
/// `hivox eval sdf-error`: the paper's Table I score (cmd_experiment.cpp); under `eval`.
void add_sdf_error_command(CLI::App* eval);
/// `hivox experiment DATASET`: the paper's experiments with a report (cmd_experiment.cpp).
void add_experiment_command(CLI::App& app);

}  // namespace hivox::cli

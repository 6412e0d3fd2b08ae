#pragma once
// Config files (`--config FILE`): a run's settings as JSON, keyed by the command's option names.
// A run writes its effective settings as `config.json` (every option of the command, given or
// default); `--config` reads such a file back, and options given on the command line override
// it, so that `hivox reconstruct DATASET --config OUT/config.json` repeats a run.

#include <string>
#include <vector>

#include <CLI/CLI.hpp>

namespace hivox::cli {

/// `hivox experiment` is left alone: its --config names configurations to compare.
/// The command line with the settings of a `--config FILE` (or `--config=FILE`) inserted after
/// the command's name, except those the command line gives itself. Throws `Error` naming the file
/// for a missing or malformed file, one written for another command, an option `app`'s command
/// does not have, or a value that is neither a number, a string, a boolean nor a list.
std::vector<std::string> expand_config_args(const std::vector<std::string>& args,
                                            const CLI::App& app);

/// The effective settings of `cmd` as config.json: {"hivox_version", "command", "options":
/// {"--name": value, ...}}; flags as booleans, numbers as numbers, lists as arrays. Options
/// that say where results go or how much is printed (`--out`, `--overwrite`, `--quiet`,
/// `--config`, `--save-map`, `--map`, `--help`) are left out: they are not the run's settings.
std::string effective_config_json(const CLI::App& cmd);

}  // namespace hivox::cli

#pragma once
// Running the built `hivox` program from tests.

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <string>

#include <fmt/format.h>

namespace hivox::test {

struct CliRun {
  int exit_code = -1;
  std::string output;  // stdout and stderr together
};

/// Runs a shell command line, its output and exit status.
inline CliRun run_shell(const std::string& command_line) {
  const std::string command = command_line + " 2>&1";
  CliRun run;
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) return run;
  std::array<char, 4096> buffer{};
  for (std::size_t n; (n = fread(buffer.data(), 1, buffer.size(), pipe)) > 0;)
    run.output.append(buffer.data(), n);
  const int status = pclose(pipe);
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return run;
}

/// The path of the built `hivox` program: $HIVOX_BIN where set (the tests moved off their build,
/// as bench/gpu_bundle.sh packs them), else the build's.
inline std::string hivox_binary() {
  const char* bin = std::getenv("HIVOX_BIN");
  return bin != nullptr && *bin != '\0' ? bin : HIVOX_BINARY_DIR "/hivox";
}

/// Runs the built `hivox` with `args`.
inline CliRun run_hivox(const std::string& args) {
  // Formatted, not `a + " " + b`: GCC 12 at -O3 warns falsely (-Warray-bounds) on that.
  return run_shell(fmt::format("{} {}", hivox_binary(), args));
}

/// Runs the built `hivox` with `args` (a run without --quiet: its progress line every 50
/// frames is the cue) and sends it SIGINT once it reports `frames` (a multiple of 50) fused (or
/// after 10 minutes, or not at all when it ended before); `log` keeps its output meanwhile. A fixed
/// delay is no good: under the sanitizers on a busy machine 8 s once came before the run had
/// started, and 50 frames of the desk at 640x480 took 90 s there.
inline CliRun run_hivox_interrupted(const std::string& args, int frames, const std::string& log) {
  return run_shell(
      fmt::format("{} {} > {} 2>&1 & pid=$!; "
                  "i=0; while [ $i -lt 6000 ] && kill -0 $pid 2> /dev/null && ! grep -q 'frame "
                  "{}/' {}; do sleep 0.1; i=$((i+1)); done; "
                  "kill -INT $pid; wait $pid; status=$?; cat {}; exit $status",
                  hivox_binary(), args, log, frames, log, log));
}

}  // namespace hivox::test

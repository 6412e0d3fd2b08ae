#pragma once
// Running the built `hivox` program from tests.

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace hivox::test {

struct CliRun {
  int exit_code = -1;
  std::string output;  // stdout and stderr together
};

inline CliRun run_hivox(const std::string& args) {
  const std::string command = std::string(HIVOX_BINARY_DIR) + "/hivox " + args + " 2>&1";
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

}  // namespace hivox::test

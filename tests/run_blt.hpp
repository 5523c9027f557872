#pragma once
// Runs the blt binary of this build, for tests of the command line as a user types it.
#include <doctest/doctest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <string>

struct BltRun {
  int status = -1;
  std::string output;  // stdout and stderr together
};

// `env` is prepended to the command (e.g. "BLT_MATERIALS_DIR='/tmp/x'").
inline BltRun runBlt(const std::string& args, const std::string& env = {}) {
  const std::string exe = std::string(BLT_BINARY_DIR) + "/bin/blt";
  REQUIRE_MESSAGE(std::filesystem::exists(exe), "build the blt target first: " << exe);
  const std::string command = env + (env.empty() ? "" : " ") + "'" + exe + "' " + args + " 2>&1";
  BltRun run;
  FILE* pipe = popen(command.c_str(), "r");
  REQUIRE(pipe != nullptr);
  std::array<char, 512> buf{};
  while (fgets(buf.data(), buf.size(), pipe)) run.output += buf.data();
  const int raw = pclose(pipe);
  run.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  return run;
}

#pragma once
// A fresh, empty directory for one test case: TMPDIR/blt_PREFIX_NAME_PID, emptied first (a crashed earlier run
// may have left it). The caller removes it at the end.
#include <unistd.h>

#include <filesystem>
#include <string>

inline std::filesystem::path scratchDir(const std::string& prefix, const std::string& name) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("blt_" + prefix + "_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

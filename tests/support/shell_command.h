// Running a command-line tool from a test (a validator, DCMTK's dump
// tools) and writing the bytes it reads.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

namespace cinevol::testing {

struct CommandResult {
  int status = -1;
  std::string output;  // stdout and stderr
};

// Runs `command` in the shell; its exit status and what it printed.
inline CommandResult RunCommand(const std::string& command) {
  CommandResult result;
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (pipe == nullptr) return result;
  char buffer[4096];
  for (std::size_t n; (n = fread(buffer, 1, sizeof buffer, pipe)) > 0;) result.output.append(buffer, n);
  const int status = pclose(pipe);
  result.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

inline bool Installed(const std::string& program) { return RunCommand("command -v " + program).status == 0; }

inline void WriteFile(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out << bytes;
}

}  // namespace cinevol::testing

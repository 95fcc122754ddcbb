// A cinevol-server of our own on a free loopback port, for commands that
// run end to end on one machine (`cinevol demo`, `cinevol-viewer` with no
// --server). It is the binary beside the running program, and it stops, by
// its process id, when this object goes.
#pragma once

#include <sys/types.h>

#include <filesystem>
#include <string>
#include <vector>

namespace cinevol::cli {

class LocalServer {
 public:
  // Starts the server (`backend`: auto, cpu or cuda; the built-in head
  // phantom unless `extra` flags name volumes) writing its log to `log`, and
  // waits until it listens. Throws InputError when it cannot start or stops
  // at start.
  LocalServer(const std::string& backend, const std::filesystem::path& log, const std::vector<std::string>& extra = {});
  ~LocalServer();  // SIGTERM, then SIGKILL after 15 s
  LocalServer(const LocalServer&) = delete;
  LocalServer& operator=(const LocalServer&) = delete;

  std::string address() const;  // 127.0.0.1:PORT

 private:
  pid_t pid_ = -1;
  int port_ = 0;
};

}  // namespace cinevol::cli

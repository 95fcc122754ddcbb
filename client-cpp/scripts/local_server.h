// Programs of our own on free loopback ports, for commands that run end to
// end on one machine (`cinevol demo`, `cinevol view`, `cinevol-viewer` with
// no --server): the cinevol-server and cinevol-web beside the running
// program, each stopped, by its process id, when its object goes.
#pragma once

#include <sys/types.h>

#include <filesystem>
#include <string>
#include <vector>

namespace cinevol::cli {

// A program beside this one, started with `args` and `--port-file F`, that
// writes the port it listens on to F.
class LocalProgram {
 public:
  // Starts `name` writing its log to `log` and waits until it listens (up to
  // 120 s: a server may build its phantom first). Throws InputError when it
  // is not beside this program, cannot start or stops at start.
  LocalProgram(const std::string& name, std::vector<std::string> args, const std::filesystem::path& log);
  ~LocalProgram();  // SIGTERM, then SIGKILL after 15 s
  LocalProgram(const LocalProgram&) = delete;
  LocalProgram& operator=(const LocalProgram&) = delete;

  int port() const { return port_; }
  pid_t pid() const { return pid_; }

 private:
  std::string name_;
  pid_t pid_ = -1;
  int port_ = 0;
};

// cinevol-server on 127.0.0.1, a free port.
class LocalServer {
 public:
  // `backend`: auto, cpu or cuda; the built-in head phantom unless `extra`
  // flags name volumes.
  LocalServer(const std::string& backend, const std::filesystem::path& log, std::vector<std::string> extra = {});
  std::string address() const;  // 127.0.0.1:PORT
  pid_t pid() const { return program_.pid(); }

 private:
  LocalProgram program_;
};

// cinevol-web, the browser page's gateway, on 127.0.0.1 (a free port) for `server`.
class LocalGateway {
 public:
  LocalGateway(const std::string& server, const std::filesystem::path& log, std::vector<std::string> extra = {});
  std::string url() const;  // http://127.0.0.1:PORT/
  pid_t pid() const { return program_.pid(); }

 private:
  LocalProgram program_;
};

}  // namespace cinevol::cli

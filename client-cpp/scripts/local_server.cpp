// Spawning and stopping a local cinevol-server.
#include "local_server.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <stdexcept>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "core/error.h"

extern char** environ;

namespace cinevol::cli {

namespace fs = std::filesystem;

LocalServer::LocalServer(const std::string& backend, const fs::path& log, const std::vector<std::string>& extra) {
  const fs::path program = fs::read_symlink("/proc/self/exe").parent_path() / "cinevol-server";
  if (!fs::exists(program)) throw InputError(fmt::format("{} not found beside this program", program.string()));
  const fs::path port_file = fs::path(log).replace_extension(".port");
  fs::remove(port_file);
  std::vector<std::string> args{program.string(), "--listen", "127.0.0.1:0", "--port-file", port_file.string(),
                                "--backend", backend};
  args.insert(args.end(), extra.begin(), extra.end());
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  const int spawned = posix_spawn(&pid_, program.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) throw std::runtime_error("cannot start " + program.string());
  // The built-in phantom takes a few seconds to build on a small CPU.
  for (auto end = std::chrono::steady_clock::now() + std::chrono::seconds(120);
       std::chrono::steady_clock::now() < end;) {
    std::ifstream(port_file) >> port_;
    if (port_ > 0) return;
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      throw InputError(fmt::format("cinevol-server stopped at start; see {}", log.string()));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  kill(pid_, SIGKILL);  // no destructor runs for an object whose constructor throws
  waitpid(pid_, nullptr, 0);
  throw InputError(fmt::format("cinevol-server did not start listening within 120 s; see {}", log.string()));
}

LocalServer::~LocalServer() {
  if (pid_ <= 0) return;
  kill(pid_, SIGTERM);
  for (int i = 0; i < 300; ++i) {  // up to 15 s for an orderly stop
    if (waitpid(pid_, nullptr, WNOHANG) == pid_) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  kill(pid_, SIGKILL);
  waitpid(pid_, nullptr, 0);
}

std::string LocalServer::address() const { return fmt::format("127.0.0.1:{}", port_); }

}  // namespace cinevol::cli

// Spawning and stopping local programs: cinevol-server and cinevol-web.
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

LocalProgram::LocalProgram(const std::string& name, std::vector<std::string> args, const fs::path& log)
    : name_(name) {
  const fs::path program = fs::read_symlink("/proc/self/exe").parent_path() / name;
  if (!fs::exists(program)) throw InputError(fmt::format("{} not found beside this program", program.string()));
  const fs::path port_file = fs::path(log).replace_extension(".port");
  fs::remove(port_file);
  args.insert(args.begin(), program.string());
  args.insert(args.end(), {"--port-file", port_file.string()});
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  posix_spawnattr_t attributes;  // no signal blocked in the child, whatever its parent blocks (cinevol view)
  posix_spawnattr_init(&attributes);
  sigset_t none;
  sigemptyset(&none);
  posix_spawnattr_setsigmask(&attributes, &none);
  posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETSIGMASK);
  const int spawned = posix_spawn(&pid_, program.c_str(), &actions, &attributes, argv.data(), environ);
  posix_spawnattr_destroy(&attributes);
  posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) throw std::runtime_error("cannot start " + program.string());
  for (auto end = std::chrono::steady_clock::now() + std::chrono::seconds(120);
       std::chrono::steady_clock::now() < end;) {
    std::ifstream(port_file) >> port_;
    if (port_ > 0) return;
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      throw InputError(fmt::format("{} stopped at start; see {}", name, log.string()));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  kill(pid_, SIGKILL);  // no destructor runs for an object whose constructor throws
  waitpid(pid_, nullptr, 0);
  throw InputError(fmt::format("{} did not start listening within 120 s; see {}", name, log.string()));
}

LocalProgram::~LocalProgram() {
  if (pid_ <= 0) return;
  kill(pid_, SIGTERM);
  for (int i = 0; i < 300; ++i) {  // up to 15 s for an orderly stop
    if (waitpid(pid_, nullptr, WNOHANG) == pid_) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  kill(pid_, SIGKILL);
  waitpid(pid_, nullptr, 0);
}

LocalServer::LocalServer(const std::string& backend, const fs::path& log, std::vector<std::string> extra)
    : program_("cinevol-server", [&] {
        std::vector<std::string> args{"--listen", "127.0.0.1:0", "--backend", backend};
        args.insert(args.end(), extra.begin(), extra.end());
        return args;
      }(), log) {}

std::string LocalServer::address() const { return fmt::format("127.0.0.1:{}", program_.port()); }

LocalGateway::LocalGateway(const std::string& server, const fs::path& log, std::vector<std::string> extra)
    : program_("cinevol-web", [&] {
        std::vector<std::string> args{"--listen", "127.0.0.1:0", "--server", server};
        args.insert(args.end(), extra.begin(), extra.end());
        return args;
      }(), log) {}

std::string LocalGateway::url() const { return fmt::format("http://127.0.0.1:{}/", program_.port()); }

}  // namespace cinevol::cli

// A real cinevol-server for tests: started as a child process on a free
// loopback port (it binds port 0 and reports the port in a file), reached
// through cinevol::Client, and stopped by its process id.
#pragma once

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <signal.h>
#include <fcntl.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "client.h"
#include "support/free_port.h"

extern char** environ;

namespace cinevol::testing {

// The programs under test: the build's, unless CINEVOL_SERVER / CINEVOL_CLI
// name others (a bundle on the GPU machine).
inline std::string ProgramPath(const char* variable, const char* built) {
  const char* path = std::getenv(variable);
  return path ? path : built;
}
inline std::string ServerPath() { return ProgramPath("CINEVOL_SERVER", CINEVOL_SERVER_PATH); }
inline std::string CliPath() { return ProgramPath("CINEVOL_CLI", CINEVOL_CLI_PATH); }

// Starts `program` with `args`; returns its pid (or -1).
inline pid_t Spawn(const std::string& program, const std::vector<std::string>& args,
                   const std::filesystem::path& log = {}) {
  std::vector<char*> argv{const_cast<char*>(program.c_str())};
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (!log.empty()) {
    posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
  }
  pid_t pid = -1;
  if (posix_spawn(&pid, program.c_str(), &actions, nullptr, argv.data(), environ) != 0) pid = -1;
  posix_spawn_file_actions_destroy(&actions);
  return pid;
}

// Waits up to `timeout` for `pid` to exit; returns its wait status or -1.
inline int WaitExit(pid_t pid, std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  int status = 0;
  while (std::chrono::steady_clock::now() < end) {
    if (waitpid(pid, &status, WNOHANG) == pid) return status;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return -1;
}

// Runs `program` to its end (at most `timeout`); returns its exit code (-1
// when it did not exit by itself) and everything it printed.
inline std::pair<int, std::string> RunProgram(const std::string& program, const std::vector<std::string>& args,
                                              const std::filesystem::path& log,
                                              std::chrono::milliseconds timeout = std::chrono::seconds(120)) {
  const pid_t pid = Spawn(program, args, log);
  int status = WaitExit(pid, timeout);
  if (status == -1) {
    kill(pid, SIGKILL);
    WaitExit(pid, std::chrono::seconds(5));
  }
  std::ifstream in(log);
  return {status != -1 && WIFEXITED(status) ? WEXITSTATUS(status) : -1, {std::istreambuf_iterator<char>(in), {}}};
}

class ServerProcess {
 public:
  // Starts cinevol-server with a small head phantom, plus `extra` flags;
  // with `file_limit`, under that descriptor limit (soft and hard); on
  // `port` (0: any free one).
  explicit ServerProcess(const std::filesystem::path& scratch, std::vector<std::string> extra = {},
                         const std::string& backend = "cpu", int file_limit = 0, int port = 0) {
    const std::filesystem::path port_file = scratch / "port";
    std::filesystem::remove(port_file);
    log_ = scratch / "server.log";
    std::vector<std::string> args{"--listen",         "127.0.0.1:" + std::to_string(port),
                                  "--port-file",      port_file.string(),
                                  "--backend",        backend,
                                  "--volume",         "phantom:head?size=48",
                                  "--encode-threads", "2"};
    args.insert(args.end(), extra.begin(), extra.end());
    if (file_limit > 0) {  // the shell execs the server: the pid stays its
      args.insert(args.begin(), {"-c", "ulimit -n " + std::to_string(file_limit) + " && exec \"$0\" \"$@\"",
                                 ServerPath()});
      pid_ = Spawn("/bin/sh", args, log_);
    } else {
      pid_ = Spawn(ServerPath(), args, log_);
    }
    if (pid_ <= 0) return;
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (std::chrono::steady_clock::now() < end && port_ == 0) {
      std::ifstream in(port_file);
      in >> port_;
      if (port_ == 0) std::this_thread::sleep_for(std::chrono::milliseconds(50));
      if (WaitExit(pid_, std::chrono::milliseconds(0)) != -1) {  // it died
        pid_ = -1;
        return;
      }
    }
  }
  ~ServerProcess() { Stop(); }

  bool running() const { return pid_ > 0 && port_ > 0; }
  pid_t pid() const { return pid_; }
  int port() const { return port_; }
  std::string address() const { return "127.0.0.1:" + std::to_string(port_); }
  std::string Log() const {
    std::ifstream in(log_);
    return {std::istreambuf_iterator<char>(in), {}};
  }
  // The log's last `bytes`.
  std::string LogTail(std::size_t bytes = 4000) const {
    const std::string log = Log();
    return log.size() > bytes ? log.substr(log.size() - bytes) : log;
  }
  Client Connect(const std::string& token = {}) const {
    ClientOptions options;
    options.address = address();
    options.token = token;
    return Client(options);
  }

  // SIGTERM by pid, then SIGKILL if it does not stop in time; returns its wait
  // status. A server that had ended by itself, or one whose test failed, prints
  // its log's end first: a failure's first clue.
  int Stop() {
    if (pid_ <= 0) return -1;
    int status = WaitExit(pid_, std::chrono::milliseconds(0));
    if (status != -1) {
      std::fprintf(stderr, "cinevol-server (pid %d) had ended by itself, %s %d\n", pid_,
                   WIFSIGNALED(status) ? "signal" : "exit code",
                   WIFSIGNALED(status) ? WTERMSIG(status) : WEXITSTATUS(status));
    }
    if (status != -1 || ::testing::Test::HasFailure()) {
      std::fprintf(stderr, "the end of cinevol-server's log (pid %d):\n%s\n", pid_, LogTail().c_str());
    }
    if (status == -1) {
      kill(pid_, SIGTERM);
      status = WaitExit(pid_, std::chrono::seconds(15));
    }
    if (status == -1) {
      kill(pid_, SIGKILL);
      status = WaitExit(pid_, std::chrono::seconds(5));
    }
    pid_ = -1;
    return status;
  }

  // CPU seconds the server has used (user + system), from /proc.
  double CpuSeconds() const {
    std::ifstream in("/proc/" + std::to_string(pid_) + "/stat");
    std::string field;
    double ticks = 0;
    for (int i = 1; i <= 15 && in >> field; ++i) {
      if (i == 14 || i == 15) ticks += std::stod(field);
    }
    return ticks / double(sysconf(_SC_CLK_TCK));
  }

  // Resident memory in MiB, from /proc.
  double ResidentMiB() const {
    std::ifstream in("/proc/" + std::to_string(pid_) + "/status");
    for (std::string line; std::getline(in, line);) {
      if (line.rfind("VmRSS:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
    }
    return 0;
  }

 private:
  pid_t pid_ = -1;
  int port_ = 0;
  std::filesystem::path log_;
};

}  // namespace cinevol::testing

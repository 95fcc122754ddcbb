// A real Orthanc (Debian's, with its DICOMweb plugin) for the PACS tests: its
// configuration and storage in a folder of the test's, HTTP on a free port of
// 127.0.0.1 only (loopback_bind.c, preloaded), no DICOM port, remote access
// refused, authentication on with a user made up per run; started as a child
// process, stopped by its pid, and killed by the kernel should the test
// process die first (PR_SET_PDEATHSIG).
#pragma once

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "pacs/http_session.h"
#include "pacs/pacs_config.h"
#include "support/free_port.h"

extern char** environ;

namespace cinevol::testing {

class OrthancProcess {
 public:
  static constexpr const char* kProgram = "/usr/sbin/Orthanc";
  static constexpr const char* kDicomWebPlugin = "/usr/share/orthanc/plugins/libOrthancDicomWeb.so";

  // Empty when Orthanc and its DICOMweb plugin are installed; else what is missing.
  static std::string WhatIsMissing() {
    if (!std::filesystem::exists(kProgram)) return "Orthanc is not installed (scripts/install-deps.sh installs it)";
    if (!std::filesystem::exists(kDicomWebPlugin)) {
      return "Orthanc's DICOMweb plugin is not installed (scripts/install-deps.sh installs orthanc-dicomweb)";
    }
    if (!std::filesystem::exists(CINEVOL_LOOPBACK_BIND)) return "the loopback preload was not built";
    return {};
  }

  // Starts Orthanc with its files under `folder`; running() says whether it answered /system in time.
  explicit OrthancProcess(const std::filesystem::path& folder) : folder_(folder) {
    password_ = RandomPassword();
    for (int attempt = 0; attempt < 3 && !running_; ++attempt) {  // a free port may be taken before Orthanc binds it
      port_ = FreePort();
      WriteConfiguration();
      if (!Start()) continue;
      running_ = WaitForSystem(std::chrono::seconds(30));
      if (!running_) Stop();
    }
  }
  ~OrthancProcess() { Stop(); }
  OrthancProcess(const OrthancProcess&) = delete;
  OrthancProcess& operator=(const OrthancProcess&) = delete;

  bool running() const { return running_; }
  pid_t pid() const { return pid_; }
  int port() const { return port_; }
  const std::string& password() const { return password_; }
  std::string root_url() const { return "http://127.0.0.1:" + std::to_string(port_); }
  std::string Log() const {
    std::ifstream in(folder_ / "orthanc.log");
    return {std::istreambuf_iterator<char>(in), {}};
  }

  // The DICOMweb service as cinevol configures it, with the right credentials.
  pacs::PacsConfig Pacs(const std::string& name = "orthanc-test") const {
    pacs::PacsConfig config;
    config.name = name;
    config.base_url = root_url() + "/dicom-web";
    config.credentials.kind = pacs::PacsCredentials::Kind::kBasic;
    config.credentials.user = kUser;
    config.credentials.password = password_;
    config.connect_timeout = std::chrono::seconds(2);
    config.request_timeout = std::chrono::seconds(30);
    return config;
  }

  // Stores one DICOM file through Orthanc's own REST API (POST /instances); the HTTP status.
  long Upload(const std::string& dicom) const {
    pacs::HttpRequest request;
    request.what = "an upload";
    request.url = root_url() + "/instances";
    request.post = true;
    request.headers = {"Content-Type: application/dicom"};
    request.body = dicom;
    request.max_body_bytes = 1 << 20;
    pacs::HttpSession session(RootConfig());
    return session.Perform(request).status;
  }

  // SIGTERM by pid, SIGKILL when it has not gone in 10 s.
  void Stop() {
    if (pid_ <= 0) return;
    kill(pid_, SIGTERM);
    if (!WaitExit(std::chrono::seconds(10))) {
      kill(pid_, SIGKILL);
      WaitExit(std::chrono::seconds(5));
    }
    pid_ = -1;
    running_ = false;
  }

 private:
  static constexpr const char* kUser = "cinevol-test";

  static std::string RandomPassword() {
    std::random_device random;
    return "pw-" + std::to_string(random()) + std::to_string(random());
  }

  // Orthanc's root, for its own REST API (uploads, /system).
  pacs::PacsConfig RootConfig() const {
    pacs::PacsConfig config = Pacs("orthanc-root");
    config.base_url = root_url();
    return config;
  }

  void WriteConfiguration() const {
    const std::string storage = (folder_ / "storage").string();
    std::ofstream out(folder_ / "orthanc.json");
    out << "{\n"
        << "  \"Name\": \"cinevol-test\",\n"
        << "  \"StorageDirectory\": \"" << storage << "\",\n"
        << "  \"IndexDirectory\": \"" << storage << "\",\n"
        << "  \"HttpPort\": " << port_ << ",\n"
        << "  \"HttpServerEnabled\": true,\n"
        << "  \"DicomServerEnabled\": false,\n"
        << "  \"RemoteAccessAllowed\": false,\n"
        << "  \"AuthenticationEnabled\": true,\n"
        << "  \"RegisteredUsers\": {\"" << kUser << "\": \"" << password_ << "\"},\n"
        << "  \"HttpCompressionEnabled\": false,\n"
        << "  \"ExecuteLuaEnabled\": false,\n"
        << "  \"SaveJobs\": false,\n"
        << "  \"Plugins\": [\"" << kDicomWebPlugin << "\"],\n"
        << "  \"DicomWeb\": {\"Enable\": true, \"Root\": \"/dicom-web/\", \"EnableWado\": false}\n"
        << "}\n";
  }

  bool Start() {
    std::vector<std::string> environment{std::string("LD_PRELOAD=") + CINEVOL_LOOPBACK_BIND};
    for (char** entry = environ; *entry != nullptr; ++entry) {
      if (std::string_view(*entry).rfind("LD_PRELOAD=", 0) != 0) environment.emplace_back(*entry);
    }
    std::vector<char*> envp;
    for (std::string& entry : environment) envp.push_back(entry.data());
    envp.push_back(nullptr);
    const std::string config = (folder_ / "orthanc.json").string();
    const std::string log = (folder_ / "orthanc.log").string();
    std::vector<char*> argv{const_cast<char*>(kProgram), const_cast<char*>(config.c_str()), nullptr};
    const int log_fd = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (log_fd < 0) return false;
    const pid_t parent = getpid();
    pid_ = fork();
    if (pid_ == 0) {  // the child: async-signal-safe calls only, until exec
      // Killed with the test process too, should it die before TearDownTestSuite: no Orthanc outlives its test.
      prctl(PR_SET_PDEATHSIG, SIGKILL);
      if (getppid() != parent) _exit(127);
      dup2(log_fd, 1);
      dup2(log_fd, 2);
      execve(kProgram, argv.data(), envp.data());
      _exit(127);
    }
    close(log_fd);
    return pid_ > 0;
  }

  bool WaitExit(std::chrono::milliseconds timeout) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    for (int status = 0; std::chrono::steady_clock::now() < end;) {
      if (waitpid(pid_, &status, WNOHANG) == pid_) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return false;
  }

  // Polls GET /system (with the credentials) until it answers 200, Orthanc dies or `timeout` passes.
  bool WaitForSystem(std::chrono::seconds timeout) {
    pacs::PacsConfig config = RootConfig();
    config.connect_timeout = std::chrono::milliseconds(500);
    config.request_timeout = std::chrono::seconds(2);
    pacs::HttpSession session(config);
    pacs::HttpRequest request;
    request.what = "a health check";
    request.url = root_url() + "/system";
    request.max_body_bytes = 1 << 20;
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < end) {
      if (waitpid(pid_, nullptr, WNOHANG) == pid_) {  // it died (its port taken?): reaped, not to be killed
        pid_ = -1;
        return false;
      }
      try {
        if (session.Perform(request).status == 200) return true;
      } catch (const std::exception&) {
        // not listening yet
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return false;
  }

  std::filesystem::path folder_;
  std::string password_;
  int port_ = 0;
  pid_t pid_ = -1;
  bool running_ = false;
};

}  // namespace cinevol::testing

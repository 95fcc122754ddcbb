// `cinevol view PATH | --pacs NAME[=URL] (--patient-id ID | --study UID [--series UID]) [--preset P]
// [--server ADDR] [--desktop]`: one command to look at a file or a study. Without --server it starts a
// cinevol-server of its own (and, for the page, a cinevol-web), loads the volume, prints the page's address
// (or opens cinevol-viewer with --desktop), and on Ctrl-C stops what it started.
#include <fmt/format.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>

#include "commands.h"
#include "connection_options.h"
#include "core/error.h"
#include "local_server.h"
#include "pacs_load.h"
#include "text_output.h"

extern char** environ;

namespace cinevol::cli {
namespace {

namespace fs = std::filesystem;

struct ViewOptions {
  ConnectionOptions connection;
  bool remote = false;  // --server given: nothing is started
  std::string path;     // a volume file or DICOM folder
  std::string pacs;     // NAME, or NAME=URL for a server of our own
  PacsLoad load;        // with --pacs
  std::string preset, backend = "auto", logs = ".";
  bool desktop = false;
};

// What `cinevol view` started (none with --server), stopped in reverse when it goes.
struct Started {
  std::unique_ptr<LocalServer> server;
  std::unique_ptr<LocalGateway> gateway;
};

// Blocks SIGINT and SIGTERM in this thread (before any other starts), so the
// wait below takes them instead of the default ending the process before
// what it started is stopped.
sigset_t BlockStopSignals() {
  sigset_t stop;
  sigemptyset(&stop);
  sigaddset(&stop, SIGINT);
  sigaddset(&stop, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop, nullptr);
  return stop;
}

void CheckSource(const ViewOptions& o) {
  if (o.path.empty() == o.pacs.empty()) throw InputError("view: give a volume PATH or --pacs NAME, one of them");
  if (!o.path.empty() && !fs::exists(o.path)) throw InputError(fmt::format("view: {}: no such file or folder", o.path));
  const bool with_url = o.pacs.find('=') != std::string::npos;
  if (o.remote && with_url) {
    throw InputError("view: --pacs NAME=URL is for a server of cinevol view's own; with --server name its PACS");
  }
  if (!o.remote && !o.pacs.empty() && !with_url) {
    throw InputError("view: without --server, give the PACS as --pacs NAME=URL (the server started here knows no "
                     "other)");
  }
}

// The server's flags: the file's folder as its data root, the PACS named.
std::vector<std::string> ServerFlags(const ViewOptions& o) {
  if (!o.path.empty()) return {"--data-root", fs::absolute(o.path).parent_path().string()};
  return {"--pacs", o.pacs};
}

v1::VolumeInfo LoadVolume(Client& client, const ViewOptions& o) {
  auto progress = [](const v1::LoadSeriesProgress& p) {
    fmt::print(stderr, "cinevol view: {}: {} of {} instances, {}\n", p.stage(), p.instances_done(),
               p.instances_total(), Bytes(p.bytes()));
  };
  if (!o.pacs.empty()) {
    PacsLoad load = o.load;
    load.pacs = o.pacs.substr(0, o.pacs.find('='));
    return LoadFromPacs(client, load, progress);
  }
  if (!o.remote) {  // inside the data root
    return client.LoadVolume(fs::path(o.path).filename().string(), {}, {}, o.load.resample_uneven);
  }
  if (fs::is_directory(o.path)) {
    throw InputError("view: a DICOM folder reaches a remote server through its data roots or PACS; upload a file, or "
                     "leave out --server");
  }
  return client.UploadVolume(o.path);
}

// The page's address for `volume`, the token (if any) in the fragment, where the page keeps it out of logs.
std::string PageUrl(const std::string& base, const ViewOptions& o, const std::string& volume) {
  std::string url = fmt::format("{}?volume={}", base, volume);
  if (!o.preset.empty()) url += "&preset=" + o.preset;
  if (!o.connection.token.empty()) url += "#token=" + o.connection.token;
  return url;
}

// cinevol-viewer beside this program on the volume; waits for it or a stop signal.
void RunDesktop(const ViewOptions& o, const std::string& server, const std::string& volume, const sigset_t& stop) {
  const fs::path viewer = fs::read_symlink("/proc/self/exe").parent_path() / "cinevol-viewer";
  if (!fs::exists(viewer)) throw InputError(fmt::format("view: {} not found beside this program", viewer.string()));
  std::vector<std::string> args{viewer.string(), "--server", server, "--volume", volume};
  if (!o.preset.empty()) args.insert(args.end(), {"--preset", o.preset});
  if (!o.connection.token.empty()) args.insert(args.end(), {"--token", o.connection.token});
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawnattr_t attributes;  // the viewer takes Ctrl-C itself: signals unblocked in it
  posix_spawnattr_init(&attributes);
  sigset_t none;
  sigemptyset(&none);
  posix_spawnattr_setsigmask(&attributes, &none);
  posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETSIGMASK);
  pid_t pid = -1;
  const int spawned = posix_spawn(&pid, viewer.c_str(), nullptr, &attributes, argv.data(), environ);
  posix_spawnattr_destroy(&attributes);
  if (spawned != 0) throw std::runtime_error("cannot start " + viewer.string());
  fmt::print("cinevol view: cinevol-viewer (pid {}) on {}; close its window or press Ctrl-C to stop\n", pid, volume);
  std::fflush(stdout);
  for (;;) {
    if (waitpid(pid, nullptr, WNOHANG) == pid) return;
    const timespec tick{0, 200'000'000};
    if (sigtimedwait(&stop, nullptr, &tick) > 0) {
      kill(pid, SIGTERM);
      waitpid(pid, nullptr, 0);
      return;
    }
  }
}

void Run(const ViewOptions& o) {
  CheckSource(o);
  const sigset_t stop = BlockStopSignals();
  Started started;
  std::string server = o.connection.server;
  if (!o.remote) {
    fmt::print("cinevol view: starting cinevol-server ({} backend)...\n", o.backend);
    std::fflush(stdout);
    started.server = std::make_unique<LocalServer>(o.backend, fs::path(o.logs) / "cinevol-view-server.log",
                                                   ServerFlags(o));
    server = started.server->address();
  }
  ConnectionOptions connection = o.connection;
  connection.server = server;
  Client client = Connect(connection);
  const v1::VolumeInfo volume = LoadVolume(client, o);
  fmt::print("cinevol view: volume {} ({}, {}) on server {}{}\n", volume.id(), KindName(volume.kind()),
             volume.default_preset(), server, started.server ? fmt::format(" (pid {})", started.server->pid()) : "");
  std::fflush(stdout);
  if (o.desktop) return RunDesktop(o, server, volume.id(), stop);
  std::vector<std::string> gateway_flags;
  if (!o.connection.tls_ca.empty()) gateway_flags = {"--server-tls-ca", o.connection.tls_ca};
  started.gateway = std::make_unique<LocalGateway>(server, fs::path(o.logs) / "cinevol-view-web.log", gateway_flags);
  fmt::print("cinevol view: cinevol-web (pid {}); open {}\nPress Ctrl-C to stop {}.\n", started.gateway->pid(),
             PageUrl(started.gateway->url(), o, volume.id()),
             started.server ? "the server and the gateway" : "the gateway");
  std::fflush(stdout);
  sigwaitinfo(&stop, nullptr);
  fmt::print("cinevol view: stopping\n");
}

}  // namespace

void AddViewCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "view", "Look at a volume file or a PACS study in the browser page (or --desktop): starts what it needs");
  auto o = std::make_shared<ViewOptions>();
  AddConnectionOptions(cmd, o->connection);
  AddCallTimeoutOption(cmd, o->connection);
  cmd->add_option("path", o->path, "A volume file or DICOM folder");
  cmd->add_option("--pacs", o->pacs,
                  "Instead of PATH: a PACS by its server's NAME (with --server), or NAME=URL for the server started "
                  "here");
  cmd->add_option("--patient-id", o->load.patient_id, "With --pacs: the patient, whose latest study is shown");
  cmd->add_option("--study", o->load.study, "With --pacs: a Study Instance UID instead of --patient-id");
  cmd->add_option("--series", o->load.series, "With --study: the series (default: the study's largest)");
  cmd->add_option("--preset", o->preset, "The transfer-function preset (default: the volume's)");
  cmd->add_flag("--resample-uneven", o->load.resample_uneven, kResampleUnevenHelp);
  cmd->add_option("--backend", o->backend, "The server started here: auto, cpu or cuda")
      ->check(CLI::IsMember({"auto", "cpu", "cuda"}));
  cmd->add_option("--logs", o->logs, "Where the started programs write their logs")->capture_default_str();
  cmd->add_flag("--desktop", o->desktop, "Open cinevol-viewer instead of printing the page's address");
  cmd->callback([o, cmd] {
    ViewOptions options = *o;
    options.remote = cmd->count("--server") > 0;
    Run(options);
  });
}

}  // namespace cinevol::cli

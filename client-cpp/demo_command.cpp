// `cinevol demo`: the README's first command, end to end through the real
// service. Starts a local cinevol-server (the best backend, the built-in head
// phantom), plays examples/scripts/demo.jsonl over gRPC (a camera orbit, a
// light moving, a transfer-function edit, then idle refinement), writes the
// frames, a contact sheet and a summary, and stops the server.
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <thread>

#include <fmt/format.h>

#include "commands.h"
#include "core/error.h"
#include "demo_script.h"
#include "frame_recorder.h"
#include "script_player.h"

extern char** environ;

namespace cinevol::cli {
namespace {

namespace fs = std::filesystem;

struct DemoOptions {
  std::string out = "cinevol-demo";
  std::string backend = "auto";
};

// A cinevol-server of our own on a free loopback port, stopped by its pid.
class LocalServer {
 public:
  LocalServer(const std::string& backend, const fs::path& folder) {
    const fs::path program = fs::read_symlink("/proc/self/exe").parent_path() / "cinevol-server";
    if (!fs::exists(program)) throw InputError(fmt::format("{} not found beside cinevol", program.string()));
    const fs::path port_file = folder / "server.port", log = folder / "server.log";
    fs::remove(port_file);
    const std::vector<std::string> args{program.string(), "--listen", "127.0.0.1:0", "--port-file",
                                        port_file.string(), "--backend", backend};
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
    throw InputError(fmt::format("cinevol-server did not start listening within 120 s; see {}", log.string()));
  }
  ~LocalServer() {
    if (pid_ <= 0) return;
    kill(pid_, SIGTERM);
    for (int i = 0; i < 300; ++i) {  // up to 15 s for an orderly stop
      if (waitpid(pid_, nullptr, WNOHANG) == pid_) return;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    kill(pid_, SIGKILL);
    waitpid(pid_, nullptr, 0);
  }
  std::string address() const { return fmt::format("127.0.0.1:{}", port_); }

 private:
  pid_t pid_ = -1;
  int port_ = 0;
};

void Run(const DemoOptions& o) {
  const fs::path out = o.out;
  fs::create_directories(out);
  fmt::print("cinevol demo: starting cinevol-server ({} backend, built-in head phantom)...\n", o.backend);
  std::fflush(stdout);
  LocalServer server(o.backend, out);
  ClientOptions options;
  options.address = server.address();
  Client client(options);
  const v1::ServerStatus status = client.Status();
  const std::string device = status.devices_size() ? status.devices(0).name() : "?";
  SessionScript script = ParseScript(kDemoScript, "examples/scripts/demo.jsonl");
  // A GPU streams 1280x720; a CPU keeps up with a smaller view.
  const bool gpu = device.rfind("cuda", 0) == 0;
  script.session.viewport.set_width(gpu ? 1280 : 320);
  script.session.viewport.set_height(gpu ? 720 : 180);
  const v1::VolumeInfo volume = ResolveVolume(client, script.session);
  const auto created = client.CreateSession(SessionRequest(script.session, volume.id()));
  fmt::print("server {} on {}; session {} at {}x{}: orbit, moving light, transfer-function edit, refinement to {} "
             "spp\n",
             server.address(), device, created.session_id(), script.session.viewport.width(),
             script.session.viewport.height(), script.session.stream.target_spp());

  FrameRecorder recorder(out, 30);
  auto stream = client.Attach(created.session_id());
  int last_spp = 0;
  PlayOptions play;
  play.max_seconds = 50;
  const PlayResult r = Play(
      *stream, ExpandOrbits(script.steps, volume), play,
      [&](const ReceivedFrame& f) {
        recorder.Add(f);
        last_spp = static_cast<int>(f.frame.accumulated_spp());
      },
      [&](const PlayResult& p) {
        fmt::print("  {:4.1f} s  {:5} frames  {:6.1f} fps  {:5} spp accumulated\n", p.seconds, p.frames, p.fps(),
                   last_spp);
        std::fflush(stdout);
      });
  if (!r.status.ok()) throw RpcError({r.status.error_code(), r.error});
  client.CloseSession(created.session_id());
  stream->Finish(std::chrono::seconds(5));
  if (recorder.written().empty()) throw std::runtime_error("the server sent no frames");
  const fs::path sheet = out / "contact-sheet.png", final_frame = out / "final.jpg";
  WriteContactSheet(recorder.written(), sheet);
  fs::copy_file(recorder.written().back(), final_frame, fs::copy_options::overwrite_existing);

  const std::string summary = fmt::format(
      "cinevol demo: {} frames in {:.1f} s ({:.1f} fps) from {} on {}\n"
      "event-to-frame latency p50/p95/p99: {:.1f}/{:.1f}/{:.1f} ms over {} events\n"
      "received {:.2f} MB, {} frames dropped by newest-wins, refined to {} spp\n"
      "wrote {} frames (at most 30 per second) to {}\n"
      "wrote {} (per-frame timings), {}, {}\n",
      r.frames, r.seconds, r.fps(), server.address(), device, Percentile(r.latency_ms, 0.5),
      Percentile(r.latency_ms, 0.95), Percentile(r.latency_ms, 0.99), r.latency_ms.size(), r.bytes / 1e6, r.dropped,
      last_spp, recorder.written().size(), fs::absolute(out / "frames").string(),
      fs::absolute(recorder.csv_path()).string(), fs::absolute(sheet).string(), fs::absolute(final_frame).string());
  std::ofstream(out / "summary.txt") << summary;
  fmt::print("{}", summary);
}

}  // namespace

void AddDemoCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "demo", "Start a local server, play a scripted session over gRPC, write the frames, a contact sheet and a summary");
  auto o = std::make_shared<DemoOptions>();
  cmd->add_option("--out", o->out, "Output folder")->capture_default_str();
  cmd->add_option("--backend", o->backend, "auto, cpu or cuda")->check(CLI::IsMember({"auto", "cpu", "cuda"}));
  cmd->callback([o] { Run(*o); });
}

}  // namespace cinevol::cli

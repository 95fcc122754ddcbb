// `cinevol demo`: the README's first command, end to end through the real
// service. Starts a local cinevol-server (the best backend), loads a real CT
// (the shared data's abdomen, beside the checkout; the built-in head phantom
// where it is not there), plays examples/scripts/demo.jsonl over gRPC (a
// camera orbit, a light moving, a transfer-function edit, then idle
// refinement), writes the frames, a captioned contact sheet and a summary,
// and stops the server.
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>

#include "commands.h"
#include "core/error.h"
#include "demo_script.h"
#include "frame_recorder.h"
#include "local_server.h"
#include "script_player.h"

namespace cinevol::cli {
namespace {

namespace fs = std::filesystem;

struct DemoOptions {
  std::string out = "cinevol-demo";
  std::string backend = "auto";
  std::string volume;  // a volume file; empty: DefaultVolume()
};

// The shared data's abdominal CT (ct-body-totalsegmentator, in HU), where the
// checkout has ../shared/data beside it; empty (the built-in phantom) elsewhere.
fs::path DefaultVolume() {
  const fs::path checkout = fs::read_symlink("/proc/self/exe").parent_path().parent_path();
  const fs::path ct = checkout.parent_path() / "shared/data/ct-body-totalsegmentator/example_ct.nii.gz";
  std::error_code ec;
  return fs::is_regular_file(ct, ec) ? ct : fs::path();
}

void Run(const DemoOptions& o) {
  const fs::path out = o.out;
  fs::create_directories(out);
  const fs::path volume_file = o.volume.empty() ? DefaultVolume() : fs::absolute(o.volume);
  if (!volume_file.empty() && !fs::is_regular_file(volume_file)) {
    throw InputError(fmt::format("demo: --volume {}: no such file", o.volume));
  }
  fmt::print("cinevol demo: starting cinevol-server ({} backend, {})...\n", o.backend,
             volume_file.empty() ? "the built-in head phantom" : volume_file.filename().string());
  std::fflush(stdout);
  std::vector<std::string> flags;
  if (!volume_file.empty()) flags = {"--data-root", volume_file.parent_path().string()};
  LocalServer server(o.backend, out / "server.log", flags);
  ClientOptions options;
  options.address = server.address();
  Client client(options);
  const v1::ServerStatus status = client.Status();
  const std::string device = status.devices_size() ? status.devices(0).name() : "?";
  SessionScript script = ParseScript(kDemoScript, "examples/scripts/demo.jsonl");
  if (!volume_file.empty()) {
    script.session.volume.clear();
    script.session.load = volume_file.filename().string();
  }
  // A GPU streams 1280x720; a CPU keeps up with a smaller view, and refines it less.
  const bool gpu = device.rfind("cuda", 0) == 0;
  script.session.viewport.set_width(gpu ? 1280 : 640);
  script.session.viewport.set_height(gpu ? 720 : 360);
  if (!gpu) script.session.stream.set_target_spp(std::min(script.session.stream.target_spp(), 64u));
  const v1::VolumeInfo volume = ResolveVolume(client, script.session);
  const auto created = client.CreateSession(SessionRequest(script.session, volume.id()));
  fmt::print("server {} on {}; session {} at {}x{}: orbit, moving light, transfer-function edit, refinement to {}% "
             "estimated error or {} spp\n",
             server.address(), device, created.session_id(), script.session.viewport.width(),
             script.session.viewport.height(), 100.0f * script.session.stream.error_target(),
             script.session.stream.target_spp());

  FrameRecorder recorder(out, 30);
  auto stream = client.Attach(created.session_id());
  int last_spp = 0;
  float last_error = 0;
  PlayOptions play;
  play.max_seconds = 50;
  const PlayResult r = Play(
      *stream, ExpandOrbits(script.steps, volume), play,
      [&](const ReceivedFrame& f) {
        recorder.Add(f);
        last_spp = static_cast<int>(f.frame.accumulated_spp());
        last_error = f.frame.estimated_error();
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
  fs::copy_file(recorder.written().back().path, final_frame, fs::copy_options::overwrite_existing);

  const std::string summary = fmt::format(
      "cinevol demo: {} frames in {:.1f} s ({:.1f} fps) from {} on {}\n"
      "event-to-frame latency p50/p95/p99: {:.1f}/{:.1f}/{:.1f} ms over {} events\n"
      "received {:.2f} MB, {} frames dropped by newest-wins, refined to {} spp (estimated error {:.1f}%)\n"
      "wrote {} frames (at most 30 per second) to {}\n"
      "wrote {} (per-frame timings), {}, {}\n",
      r.frames, r.seconds, r.fps(), server.address(), device, Percentile(r.latency_ms, 0.5),
      Percentile(r.latency_ms, 0.95), Percentile(r.latency_ms, 0.99), r.latency_ms.size(), r.bytes / 1e6, r.dropped,
      last_spp, 100.0 * last_error, recorder.written().size(), fs::absolute(out / "frames").string(),
      fs::absolute(recorder.csv_path()).string(), fs::absolute(sheet).string(), fs::absolute(final_frame).string());
  std::ofstream(out / "summary.txt") << summary;
  fmt::print("{}", summary);
}

}  // namespace

void AddDemoCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "demo",
      "Start a local server, play a scripted session over gRPC, write the frames, a contact sheet and a summary");
  auto o = std::make_shared<DemoOptions>();
  cmd->add_option("--out", o->out, "Output folder")->capture_default_str();
  cmd->add_option("--backend", o->backend, "auto, cpu or cuda")->check(CLI::IsMember({"auto", "cpu", "cuda"}));
  cmd->add_option("--volume", o->volume,
                  "A volume file to show (default: the shared data's abdominal CT where it is beside the checkout, "
                  "else the built-in head phantom)");
  cmd->callback([o] { Run(*o); });
}

}  // namespace cinevol::cli

// `cinevol play --server ADDR --script FILE [--out DIR]`: replays a scripted
// interaction against a server and saves every frame and a per-frame CSV.
#include <cstdio>
#include <optional>

#include <fmt/format.h>

#include "commands.h"
#include "connection_options.h"
#include "frame_recorder.h"
#include "script_player.h"

namespace cinevol::cli {
namespace {

struct PlayCommandOptions {
  ConnectionOptions connection;
  std::string script;
  std::string out = "cinevol-play";
  std::string volume;     // overrides the script's volume, load or upload
  double timeout = 120;   // seconds the whole run may take
  // Refinement settings over the script's (docs/api.md, StreamSettings); unset keeps the script's.
  std::optional<int> target_spp;
  std::optional<float> error_target;
  std::string final_format;  // "", "jpeg" or "png"
};

void OverrideRefinement(const PlayCommandOptions& o, v1::StreamSettings& stream) {
  if (o.target_spp) stream.set_target_spp(std::uint32_t(*o.target_spp));
  if (o.error_target) stream.set_error_target(*o.error_target);
  if (!o.final_format.empty()) {
    stream.set_final_format(o.final_format == "png" ? v1::FINAL_FORMAT_PNG : v1::FINAL_FORMAT_JPEG);
  }
}

void Run(const PlayCommandOptions& o) {
  SessionScript script = LoadScript(o.script);
  OverrideRefinement(o, script.session.stream);
  Client client = Connect(o.connection);
  const v1::VolumeInfo volume =
      o.volume.empty() ? ResolveVolume(client, script.session) : ResolveVolume(client, o.volume);
  const auto created = client.CreateSession(SessionRequest(script.session, volume.id()));
  FrameRecorder recorder(o.out);
  auto stream = client.Attach(created.session_id());
  PlayOptions play;
  play.max_seconds = o.timeout;
  const PlayResult r =
      Play(*stream, ExpandOrbits(script.steps, volume), play, [&](const ReceivedFrame& f) { recorder.Add(f); });
  if (!r.status.ok()) throw RpcError({r.status.error_code(), r.error});
  client.CloseSession(created.session_id());
  stream->Finish(std::chrono::seconds(5));
  fmt::print("played {} on {} ({}): {} events, {} frames in {:.1f} s ({:.1f} fps), latency p50/p95/p99 "
             "{:.1f}/{:.1f}/{:.1f} ms, {:.1f} MB, {} dropped\nwrote {} frames to {} and {}\n",
             script.name, o.connection.server, created.device(), r.events, r.frames, r.seconds, r.fps(),
             Percentile(r.latency_ms, 0.5), Percentile(r.latency_ms, 0.95), Percentile(r.latency_ms, 0.99),
             r.bytes / 1e6, r.dropped, recorder.written().size(), (std::filesystem::path(o.out) / "frames").string(),
             recorder.csv_path().string());
  if (r.seconds >= o.timeout) std::fprintf(stderr, "cinevol play: stopped at --timeout %.0f s\n", o.timeout);
}

}  // namespace

void AddPlayCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("play", "Replay a session script against a server; save frames and a CSV");
  auto o = std::make_shared<PlayCommandOptions>();
  AddConnectionOptions(cmd, o->connection);
  cmd->add_option("--script", o->script, "Session script (JSON Lines; docs/client.md)")->required();
  cmd->add_option("--out", o->out, "Output folder")->capture_default_str();
  cmd->add_option("--volume", o->volume, "Volume id, instead of the script's volume, load or upload");
  cmd->add_option("--timeout", o->timeout, "Seconds the run may take at most")->check(CLI::Range(0.1, 86400.0))
      ->capture_default_str();
  cmd->add_option("--target-spp", o->target_spp,
                  "Refinement's cap in samples per pixel (default: the script's, else 256)")
      ->check(CLI::Range(1, 65536));
  cmd->add_option("--error-target", o->error_target,
                  "Refinement ends at this estimated relative error (default: the script's, else 0.02; 0: at the cap)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--final-format", o->final_format,
                  "The final frame as jpeg or png (lossless; default: the script's, else jpeg)")
      ->check(CLI::IsMember({"jpeg", "png"}));
  cmd->callback([o] { Run(*o); });
}

}  // namespace cinevol::cli

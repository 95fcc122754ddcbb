// `cinevol play --server ADDR --script FILE [--out DIR]`: replays a scripted
// interaction against a server and saves every frame and a per-frame CSV,
// and the script's slices (slices/NAME.png) and picks (picks.csv).
#include <fmt/format.h>

#include <cstdio>
#include <fstream>
#include <optional>

#include "commands.h"
#include "connection_options.h"
#include "core/error.h"
#include "encode/image_codecs.h"
#include "frame_recorder.h"
#include "script_player.h"

namespace cinevol::cli {
namespace {

struct PlayCommandOptions {
  ConnectionOptions connection;
  std::string script;
  std::string out = "cinevol-play";
  std::string volume;    // overrides the script's volume, load or upload
  double timeout = 120;  // seconds the whole run may take
  // Refinement settings over the script's (docs/api.md, StreamSettings); unset keeps the script's.
  std::optional<int> target_spp;
  std::optional<float> error_target;
  std::string final_format;  // "", "jpeg" or "png"
};

// A CSV field: quoted when it holds a comma, a quote or a line break (RFC 4180).
std::string CsvField(const std::string& text) {
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (const char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

// Makes a script's slice and pick calls on its session and writes their
// answers: slices to `folder`/slices/NAME.png, picks as lines of
// `folder`/picks.csv. Each is created with the first call that needs it.
class ReadingRecorder {
 public:
  ReadingRecorder(Client& client, std::string session_id, const std::filesystem::path& folder)
      : client_(client),
        session_id_(std::move(session_id)),
        slices_dir_(folder / "slices"),
        picks_path_(folder / "picks.csv") {}

  void Call(const ScriptStep& step) {
    try {
      if (step.call->slice) Slice(*step.call);
      if (step.call->pick) Pick(step);
    } catch (const RpcError& e) {  // "CODE: message" -> "CODE: script line N: message"
      const std::string message = std::string(e.what()).substr(StatusCodeName(e.code()).size() + 2);
      throw RpcError(
          {e.code(), fmt::format("script line {}: {}: {}", step.line, step.call->slice ? "slice" : "pick", message)});
    }
  }

  int slices() const { return slices_; }
  int picks() const { return picks_; }
  const std::filesystem::path& slices_dir() const { return slices_dir_; }
  const std::filesystem::path& picks_path() const { return picks_path_; }

 private:
  void Slice(const ScriptCall& call) {
    v1::SliceRequest request = *call.slice;
    request.set_session_id(session_id_);
    const v1::SliceImage image = client_.RenderSlice(request);
    std::filesystem::create_directories(slices_dir_);
    WriteFile(slices_dir_ / call.out, std::vector<std::uint8_t>(image.png().begin(), image.png().end()));
    ++slices_;
  }

  void Pick(const ScriptStep& step) {
    v1::PickRequest request = *step.call->pick;
    request.set_session_id(session_id_);
    const v1::PickResult r = client_.Pick(request);
    if (!csv_.is_open()) {
      csv_.open(picks_path_);
      if (!csv_) throw InputError(fmt::format("{}: cannot write", picks_path_.string()));
      csv_ << "line,at,x,y,hit,lps_x_mm,lps_y_mm,lps_z_mm,value,label_value,label_name\n";
    }
    csv_ << fmt::format("{},{:g},{:g},{:g},{}", step.line, step.at, request.x(), request.y(), r.hit() ? 1 : 0);
    if (r.hit()) {
      const v1::Vec3& p = r.position_mm();
      csv_ << fmt::format(",{:g},{:g},{:g},{:g}", p.x(), p.y(), p.z(), r.value());
    } else {
      csv_ << ",,,,";
    }
    if (r.has_label()) {
      csv_ << fmt::format(",{},{}\n", r.label().value(), CsvField(r.label().name()));
    } else {
      csv_ << ",,\n";
    }
    csv_.flush();
    ++picks_;
  }

  Client& client_;
  const std::string session_id_;
  const std::filesystem::path slices_dir_, picks_path_;
  std::ofstream csv_;
  int slices_ = 0, picks_ = 0;
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
  // At once, while it plays: `cinevol share --session ID` needs it.
  fmt::print("session {} on {}\n", created.session_id(), created.device());
  std::fflush(stdout);
  FrameRecorder recorder(o.out);
  ReadingRecorder reading(client, created.session_id(), o.out);
  auto stream = client.Attach(created.session_id());
  PlayOptions play;
  play.max_seconds = o.timeout;
  play.on_call = [&](const ScriptStep& step) { reading.Call(step); };
  PlayResult r;
  try {
    r = Play(*stream, WithCalls(ExpandOrbits(script.steps, volume), script.calls), play,
             [&](const ReceivedFrame& f) { recorder.Add(f); });
  } catch (const RpcError&) {  // a slice or pick refused: the session is of no further use
    stream->Cancel();
    try {
      client.CloseSession(created.session_id());
    } catch (const RpcError&) {  // the call's error is the one to tell
    }
    throw;
  }
  if (!r.status.ok()) throw RpcError({r.status.error_code(), r.error});
  client.CloseSession(created.session_id());
  stream->Finish(std::chrono::seconds(5));
  fmt::print(
      "played {} on {} ({}): {} events, {} frames in {:.1f} s ({:.1f} fps), latency p50/p95/p99 "
      "{:.1f}/{:.1f}/{:.1f} ms, {:.1f} MB, {} dropped\nwrote {} frames to {} and {}\n",
      script.name, o.connection.server, created.device(), r.events, r.frames, r.seconds, r.fps(),
      Percentile(r.latency_ms, 0.5), Percentile(r.latency_ms, 0.95), Percentile(r.latency_ms, 0.99), r.bytes / 1e6,
      r.dropped, recorder.written().size(), (std::filesystem::path(o.out) / "frames").string(),
      recorder.csv_path().string());
  if (reading.slices() > 0) fmt::print("wrote {} slices to {}\n", reading.slices(), reading.slices_dir().string());
  if (reading.picks() > 0) fmt::print("wrote {} picks to {}\n", reading.picks(), reading.picks_path().string());
  const int calls = int(script.calls.size()), made = reading.slices() + reading.picks();
  if (made < calls) {
    std::fprintf(stderr, "cinevol play: %d of the script's %d slice and pick lines were not reached\n", calls - made,
                 calls);
  }
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
  cmd->add_option("--timeout", o->timeout, "Seconds the run may take at most")
      ->check(CLI::Range(0.1, 86400.0))
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

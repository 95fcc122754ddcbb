// `cinevol loadtest --server ADDR --sessions N --seconds S [--script FILE]
// [--viewers V] [--ramp-seconds R]`: N concurrent sessions (starting evenly
// over R seconds), each playing a script in a loop (by default an orbit with
// camera events at a fixed rate, as a dragging mouse sends them), for S
// seconds, each shared with V viewers watching by a link (docs/sharing.md). Reports frames per second, event-to-frame latency, the
// server's stage times, bytes, dropped frames, the viewers' frames per second
// and errors by status code, as a table or JSON.
#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <numeric>
#include <thread>

#include "commands.h"
#include "connection_options.h"
#include "scene/scene_file.h"
#include "script_player.h"
#include "sharing_calls.h"

namespace cinevol::cli {
namespace {

struct LoadtestOptions {
  ConnectionOptions connection;
  int sessions = 1;
  double seconds = 10;
  double ramp_seconds = 0;  // sessions start evenly over this long; 0: all at once
  std::string script;  // a session script played in a loop; default: an orbit
  int width = 1280, height = 720, spp = 2;
  std::string denoiser = "wrls";
  std::string volume;  // default: the script's (volume, load or upload), else the server's first volume
  std::string preset = "ct-bone";
  std::string scene;  // a scene file to start from instead of the preset (its volume is ignored)
  double event_hz = 120;
  double degrees_per_second = 120;
  int jpeg_quality = 80;
  float interactive_frame_ms = -1;  // < 0: the server's default (70 ms on a CPU server, else off)
  bool server_upsamples = false;    // smaller frames upsampled by the server, not left to the client
  int viewers = 0;                  // per session, watching by a link
  bool json = false;
  std::string out;
};

struct SessionResult {
  std::string id;
  std::string server;  // where the session lived (the one it ended on)
  PlayResult play;
  std::vector<double> viewer_fps;  // each viewer's frames received a second
  std::string error;               // status code name (or CLIENT), empty when none
  std::string error_message;
};

v1::Denoiser ParseDenoiser(const std::string& name) {
  static const std::map<std::string, v1::Denoiser> kNames = {
      {"none", v1::DENOISER_NONE}, {"accumulate", v1::DENOISER_ACCUMULATE},
      {"knn", v1::DENOISER_KNN},   {"guided", v1::DENOISER_GUIDED},
      {"svgf", v1::DENOISER_SVGF}, {"wrls", v1::DENOISER_WRLS}};
  return kNames.at(name);
}

// The script each session plays: --script, or an orbit built from the flags.
SessionScript MakeScript(const LoadtestOptions& o) {
  if (!o.script.empty()) return LoadScript(o.script);
  SessionScript s;
  s.name = "built-in orbit";
  s.session.viewport.set_width(o.width);
  s.session.viewport.set_height(o.height);
  s.session.preset = o.preset;
  if (!o.scene.empty()) s.session.scene = LoadSceneFile(o.scene);
  s.session.stream.set_denoiser(ParseDenoiser(o.denoiser));
  s.session.stream.set_jpeg_quality(o.jpeg_quality);
  if (o.interactive_frame_ms >= 0) s.session.stream.set_interactive_frame_ms(o.interactive_frame_ms);
  s.session.stream.set_frames_at_rendered_size(!o.server_upsamples);  // as cinevol's page and viewer ask
  s.session.stream.set_target_spp(65536);  // keep rendering: every frame counts
  s.session.stream.set_error_target(0);
  ScriptStep spp;
  spp.event.mutable_render()->set_spp(o.spp);
  s.steps.push_back(spp);
  ScriptStep orbit;
  orbit.is_orbit = true;
  orbit.orbit.degrees = o.degrees_per_second * o.seconds;
  orbit.orbit.seconds = o.seconds;
  orbit.orbit.hz = o.event_hz;
  s.steps.push_back(orbit);
  return s;
}

double Mean(const std::vector<double>& v) { return std::accumulate(v.begin(), v.end(), 0.0) / double(v.size()); }

// `count` viewers watching `session_id` by a link until `stop`, each on a
// connection of its own as people on their own machines are: each one's
// frames a second, counted on threads of their own.
class Viewers {
 public:
  Viewers(const ConnectionOptions& connection, Client& owner, const std::string& session_id, int count) {
    if (count == 0) return;
    v1::ShareSessionRequest share;
    share.set_session_id(session_id);
    const std::string secret = owner.Share(share).secret();
    frames_.resize(count);
    for (int i = 0; i < count; ++i) {
      clients_.push_back(std::make_unique<Client>(Connect(connection)));
      watches_.push_back(clients_.back()->Watch(secret));
      threads_.emplace_back([this, i] {
        while (!stop_) {
          const auto message = watches_[i]->Next(std::chrono::milliseconds(100));
          if (message && message->has_frame()) ++frames_[i];
          if (!message && watches_[i]->ended()) return;
        }
      });
    }
    start_ = std::chrono::steady_clock::now();
  }
  // Stops them; each viewer's frames a second.
  std::vector<double> Stop() {
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    stop_ = true;
    for (auto& w : watches_) w->Cancel();
    for (std::thread& t : threads_) t.join();
    std::vector<double> fps;
    for (std::uint64_t n : frames_) fps.push_back(double(n) / std::max(seconds, 1e-3));
    return fps;
  }

 private:
  std::vector<std::unique_ptr<Client>> clients_;
  std::vector<std::unique_ptr<SessionWatch>> watches_;
  std::vector<std::uint64_t> frames_;
  std::vector<std::thread> threads_;
  std::atomic<bool> stop_{false};
  std::chrono::steady_clock::time_point start_;
};

SessionResult RunSession(const LoadtestOptions& o, Client& client, const SessionScript& script,
                         const v1::VolumeInfo& volume, int index) {
  SessionResult r;
  try {
    const auto created = client.CreateSession(SessionRequest(script.session, volume.id()));
    r.id = created.session_id();
    r.server = client.SessionAddress(r.id);
    std::vector<ScriptStep> steps = script.steps;
    for (ScriptStep& s : steps) s.orbit.start_degrees += 37.0 * index;  // sessions look at different sides
    auto stream = client.Attach(r.id);
    Viewers viewers(o.connection, client, r.id, o.viewers);
    PlayOptions play;
    play.max_seconds = o.seconds;
    play.loop = true;
    play.wait_final = false;
    r.play = Play(*stream, ExpandOrbits(steps, volume), play);
    r.viewer_fps = viewers.Stop();
    r.server = client.SessionAddress(r.id);  // a failover may have moved it
    if (!r.play.status.ok()) {
      r.error = StatusCodeName(r.play.status.error_code());
      r.error_message = r.error + ": " + r.play.error;
      return r;
    }
    client.CloseSession(r.id);
    stream->Finish(std::chrono::seconds(5));
  } catch (const RpcError& e) {
    r.error = StatusCodeName(e.code());
    r.error_message = e.what();
  } catch (const std::exception& e) {
    r.error = "CLIENT";
    r.error_message = e.what();
  }
  return r;
}

struct Summary {
  double fps_min = INFINITY, fps_total = 0, fps_mean = 0;
  std::vector<double> viewer_fps;  // every viewer of every session
  std::vector<double> latencies;
  std::uint64_t frames = 0, bytes = 0, dropped = 0;
  PlayResult stages;  // stage sums over every session
  std::map<std::string, int> errors;
};

Summary Summarise(const std::vector<SessionResult>& results) {
  Summary s;
  for (const SessionResult& r : results) {
    if (!r.error.empty()) ++s.errors[r.error];
    s.fps_min = std::min(s.fps_min, r.play.fps());
    s.fps_total += r.play.fps();
    s.viewer_fps.insert(s.viewer_fps.end(), r.viewer_fps.begin(), r.viewer_fps.end());
    s.latencies.insert(s.latencies.end(), r.play.latency_ms.begin(), r.play.latency_ms.end());
    s.frames += r.play.frames;
    s.bytes += r.play.bytes;
    s.dropped += r.play.dropped;
    for (int i = 0; i < 7; ++i) s.stages.stage_us_sum[i] += r.play.stage_us_sum[i];
    s.stages.stage_frames += r.play.stage_frames;
    s.stages.smaller_frames += r.play.smaller_frames;
    s.stages.transfer_frames += r.play.transfer_frames;
  }
  s.fps_mean = results.empty() ? 0 : s.fps_total / double(results.size());
  return s;
}

std::string Table(const LoadtestOptions& o, const SessionScript& script, const std::string& device,
                  const std::vector<SessionResult>& results, const Summary& s) {
  const auto& viewport = script.session.viewport;
  std::string t = fmt::format(
      "cinevol loadtest: {} session(s) x {:.0f} s on {} ({}), {}x{}, script: {}\n\n"
      "| session | frames | fps | latency p50 ms | p95 ms | p99 ms | MB | dropped | error |\n"
      "|---|---|---|---|---|---|---|---|---|\n",
      o.sessions, o.seconds, o.connection.server, device, viewport.width(), viewport.height(),
      o.script.empty() ? fmt::format("orbit, {} spp, {}, camera events at {:.0f} Hz", o.spp, o.denoiser, o.event_hz)
                       : script.name);
  for (const SessionResult& r : results) {
    t += fmt::format("| {} | {} | {:.1f} | {:.1f} | {:.1f} | {:.1f} | {:.1f} | {} | {} |\n", r.id, r.play.frames,
                     r.play.fps(), Percentile(r.play.latency_ms, 0.5), Percentile(r.play.latency_ms, 0.95),
                     Percentile(r.play.latency_ms, 0.99), r.play.bytes / 1e6, r.play.dropped,
                     r.error.empty() ? "-" : r.error);
  }
  t += fmt::format("| all | {} | {:.1f} (min {:.1f}, total {:.1f}) | {:.1f} | {:.1f} | {:.1f} | {:.1f} | {} | {} |\n\n",
                   s.frames, s.fps_mean, s.fps_min, s.fps_total, Percentile(s.latencies, 0.5),
                   Percentile(s.latencies, 0.95), Percentile(s.latencies, 0.99), s.bytes / 1e6, s.dropped,
                   s.errors.size());
  t += "mean per frame, ms:";
  for (int i = 0; i < 7; ++i) t += fmt::format(" {} {:.2f}{}", kStageNames[i], s.stages.StageMs(i), i < 6 ? "," : "\n");
  t += "(queue: event arrival to render start; server: event arrival to send start; transfer: the rest of the "
       "latency, i.e. send, network and client)\n";
  if (s.stages.smaller_frames > 0) {
    t += fmt::format("frames rendered smaller while moving (interactive resolution): {} of {} ({:.0f}%)\n",
                     s.stages.smaller_frames, s.frames, 100.0 * double(s.stages.smaller_frames) / double(s.frames));
  }
  if (!s.viewer_fps.empty()) {
    t += fmt::format("viewers: {} per session by a link; frames received a second: mean {:.1f}, min {:.1f}\n",
                     o.viewers, Mean(s.viewer_fps), *std::min_element(s.viewer_fps.begin(), s.viewer_fps.end()));
  }
  for (const auto& [code, n] : s.errors) t += fmt::format("errors {}: {}\n", code, n);
  std::map<std::string, int> per_server;
  for (const SessionResult& r : results) {
    if (!r.server.empty()) ++per_server[r.server];
  }
  if (per_server.size() > 1) {
    t += "sessions per server:";
    for (const auto& [server, n] : per_server) t += fmt::format(" {} {};", server, n);
    t.back() = '\n';
  }
  for (const SessionResult& r : results) {
    if (!r.error.empty()) t += fmt::format("session {}: {}\n", r.id.empty() ? "?" : r.id, r.error_message);
  }
  return t;
}

std::string Json(const LoadtestOptions& o, const SessionScript& script, const std::string& device,
                 const std::vector<SessionResult>& results, const Summary& s) {
  auto number = [](double v) { return std::isfinite(v) ? fmt::format("{:.3f}", v) : std::string("null"); };
  auto latency = [&](const std::vector<double>& v) {
    return fmt::format("{{\"p50\": {}, \"p95\": {}, \"p99\": {}}}", number(Percentile(v, 0.5)),
                       number(Percentile(v, 0.95)), number(Percentile(v, 0.99)));
  };
  std::string j = fmt::format(
      "{{\"server\": \"{}\", \"device\": \"{}\", \"sessions\": {}, \"seconds\": {}, \"width\": {}, \"height\": {}, "
      "\"script\": \"{}\",\n \"per_session\": [",
      o.connection.server, device, o.sessions, o.seconds, script.session.viewport.width(),
      script.session.viewport.height(), o.script.empty() ? "built-in orbit" : o.script);
  for (std::size_t i = 0; i < results.size(); ++i) {
    const SessionResult& r = results[i];
    j += fmt::format(
        "{}\n  {{\"id\": \"{}\", \"server\": \"{}\", \"frames\": {}, \"fps\": {}, \"latency_ms\": {}, "
        "\"bytes\": {}, \"dropped\": {}, \"error\": \"{}\"}}",
        i ? "," : "", r.id, r.server, r.play.frames, number(r.play.fps()), latency(r.play.latency_ms), r.play.bytes,
        r.play.dropped, r.error);
  }
  j += fmt::format(
      "],\n \"overall\": {{\"frames\": {}, \"fps_mean\": {}, \"fps_min\": {}, \"fps_total\": {}, "
      "\"latency_ms\": {}, \"bytes\": {}, \"dropped\": {}, \"smaller_frames\": {}, \"stage_ms\": {{",
      s.frames, number(s.fps_mean), number(s.fps_min), number(s.fps_total), latency(s.latencies), s.bytes, s.dropped,
      s.stages.smaller_frames);
  for (int i = 0; i < 7; ++i)
    j += fmt::format("{}\"{}\": {}", i ? ", " : "", kStageNames[i], number(s.stages.StageMs(i)));
  j += fmt::format("}}, \"viewers\": {}, \"viewer_fps_mean\": {}, \"viewer_fps_min\": {}", o.viewers,
                   number(s.viewer_fps.empty() ? NAN : Mean(s.viewer_fps)),
                   number(s.viewer_fps.empty() ? NAN : *std::min_element(s.viewer_fps.begin(), s.viewer_fps.end())));
  j += ", \"errors\": {";
  bool first = true;
  for (const auto& [code, n] : s.errors) {
    j += fmt::format("{}\"{}\": {}", first ? "" : ", ", code, n);
    first = false;
  }
  return j + "}}}\n";
}

int Run(const LoadtestOptions& o) {
  const SessionScript script = MakeScript(o);
  Client client = Connect(o.connection);
  const v1::VolumeInfo volume =
      o.volume.empty() ? ResolveVolume(client, script.session) : ResolveVolume(client, o.volume);
  std::string device;
  const v1::ServerStatus status = client.Status();
  for (const v1::DeviceStatus& d : status.devices()) device += (device.empty() ? "" : ", ") + d.name();

  std::vector<SessionResult> results(o.sessions);
  std::vector<std::thread> threads;
  for (int i = 0; i < o.sessions; ++i) {
    threads.emplace_back([&, i] {
      std::this_thread::sleep_for(std::chrono::duration<double>(o.ramp_seconds * i / o.sessions));
      results[i] = RunSession(o, client, script, volume, i);
    });
  }
  for (std::thread& t : threads) t.join();
  const Summary summary = Summarise(results);
  const std::string report =
      o.json ? Json(o, script, device, results, summary) : Table(o, script, device, results, summary);
  std::fputs(report.c_str(), stdout);
  if (!o.out.empty()) std::ofstream(o.out, std::ios::app) << report;
  return summary.errors.empty() ? 0 : 1;
}

}  // namespace

void AddLoadtestCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("loadtest", "Concurrent scripted sessions against a server: fps, latency, errors");
  auto o = std::make_shared<LoadtestOptions>();
  AddConnectionOptions(cmd, o->connection);
  cmd->add_option("--sessions", o->sessions, "Concurrent sessions")->check(CLI::Range(1, 1024))->capture_default_str();
  cmd->add_option("--seconds", o->seconds, "How long each session runs")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
  cmd->add_option("--ramp-seconds", o->ramp_seconds,
                  "Start the sessions evenly over this many seconds, as viewers arrive, not all at once")
      ->check(CLI::Range(0.0, 3600.0))
      ->capture_default_str();
  cmd->add_option("--script", o->script, "Session script (JSON Lines) each session plays in a loop; default: an orbit");
  cmd->add_option("--width", o->width, "Viewport width (orbit)")->check(CLI::Range(1, 8192))->capture_default_str();
  cmd->add_option("--height", o->height, "Viewport height (orbit)")->check(CLI::Range(1, 8192))->capture_default_str();
  cmd->add_option("--spp", o->spp, "Samples per pixel per frame (orbit)")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  cmd->add_option("--denoiser", o->denoiser, "none, accumulate, knn, guided, svgf or wrls (orbit)")
      ->check(CLI::IsMember({"none", "accumulate", "knn", "guided", "svgf", "wrls"}))
      ->capture_default_str();
  cmd->add_option("--volume", o->volume,
                  "Volume id (default: the script's volume, load or upload, else the server's first)");
  cmd->add_option("--preset", o->preset, "Transfer-function preset (orbit)")->capture_default_str();
  cmd->add_option("--scene", o->scene, "Start from this scene file instead of the preset (orbit)");
  cmd->add_option("--event-hz", o->event_hz, "Camera events per second per session (orbit)")
      ->check(CLI::Range(0.1, 1000.0))
      ->capture_default_str();
  cmd->add_option("--jpeg-quality", o->jpeg_quality, "JPEG quality (orbit)")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  cmd->add_option("--interactive-frame-ms", o->interactive_frame_ms,
                  "Frame-time budget while the view moves: frames render smaller to meet it "
                  "(0: always full size; default: the server's, 70 ms on the CPU backend, else 0) (orbit)")
      ->check(CLI::Range(0.0f, 10000.0f));
  cmd->add_flag("--server-upsamples", o->server_upsamples,
                "Frames rendered smaller while the view moves come upsampled to the viewport, as a client that "
                "cannot stretch them asks (default: at their rendered size, as cinevol's page and viewer ask) (orbit)");
  cmd->add_option("--viewers", o->viewers,
                  "Viewers per session, watching it by a link (docs/sharing.md): the presenter's fps with them, "
                  "and theirs")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  cmd->add_flag("--json", o->json, "Print JSON instead of a table");
  cmd->add_option("--out", o->out, "Also append the report to this file");
  cmd->callback([o] {
    if (Run(*o) != 0) throw CLI::RuntimeError(1);
  });
}

}  // namespace cinevol::cli

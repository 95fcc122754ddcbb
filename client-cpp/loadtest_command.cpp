// `cinevol loadtest --server ADDR --sessions N --seconds S`: N concurrent
// sessions, each orbiting its camera with events at a fixed rate (as a
// dragging mouse sends them), for S seconds. Reports frames per second,
// event-to-frame latency (an event's send to the receipt of the first frame
// that applied it), the server's stage times, bytes, dropped frames and
// errors by status code, as a table or JSON.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <thread>

#include <fmt/format.h>

#include "client.h"
#include "commands.h"
#include "io/scene_file.h"

namespace cinevol::cli {
namespace {

using Clock = std::chrono::steady_clock;

struct LoadtestOptions {
  std::string server = "127.0.0.1:50051";
  int sessions = 1;
  double seconds = 10;
  int width = 1280, height = 720, spp = 2;
  std::string denoiser = "wrls";
  std::string volume;  // default: the server's first volume
  std::string preset = "ct-bone";
  std::string scene;   // a scene file to start from instead of the preset (its volume is ignored)
  double event_hz = 120;
  double degrees_per_event = 1.0;
  int jpeg_quality = 80;
  bool json = false;
  std::string out;
};

// What one session saw.
struct SessionResult {
  std::string id;
  std::uint64_t frames = 0, bytes = 0, dropped = 0, events = 0;
  double seconds = 0;
  std::vector<double> latency_ms;
  // Sums over frames, microseconds: render, denoise, tonemap, encode, queue, server, transfer.
  std::array<double, 7> stage_us{};
  std::uint64_t stage_frames = 0, transfer_frames = 0;
  std::string error;  // status code name, empty when none
  std::string error_message;
};

constexpr const char* kStageNames[] = {"render", "denoise", "tonemap", "encode", "queue", "server", "transfer"};

double Percentile(std::vector<double> v, double p) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(p * double(v.size())))];
}

v1::Denoiser ParseDenoiser(const std::string& name) {
  static const std::map<std::string, v1::Denoiser> kNames = {
      {"none", v1::DENOISER_NONE}, {"accumulate", v1::DENOISER_ACCUMULATE}, {"knn", v1::DENOISER_KNN},
      {"guided", v1::DENOISER_GUIDED}, {"svgf", v1::DENOISER_SVGF}, {"wrls", v1::DENOISER_WRLS}};
  return kNames.at(name);
}

// The camera `degrees` around the volume's vertical axis, from the front
// (-y, anterior in LPS), at a distance that frames the volume.
v1::Camera OrbitCamera(const v1::VolumeInfo& volume, double degrees) {
  const double ex = volume.dims().x() * volume.spacing_mm().x(), ey = volume.dims().y() * volume.spacing_mm().y(),
               ez = volume.dims().z() * volume.spacing_mm().z();
  const double radius = 0.5 * std::sqrt(ex * ex + ey * ey + ez * ez);
  const double distance = 1.02 * radius / std::sin(15.0 * M_PI / 180.0);  // fits a 30 degree field of view
  const double a = degrees * M_PI / 180.0;
  v1::Camera c;
  c.mutable_eye()->set_x(float(distance * std::sin(a)));
  c.mutable_eye()->set_y(float(-distance * std::cos(a)));
  c.mutable_target();
  c.mutable_up()->set_z(1);
  c.set_fov_y_deg(30);
  return c;
}

void AddFrame(const v1::Frame& frame, Clock::time_point now, SessionStream& stream, std::uint64_t& acknowledged,
              SessionResult& r) {
  ++r.frames;
  r.bytes += frame.jpeg().size();
  const auto& t = frame.timings();
  const double stages[] = {double(t.render_us()), double(t.denoise_us()), double(t.tonemap_us()),
                           double(t.encode_us()), double(t.queue_us()), double(t.server_us())};
  for (int i = 0; i < 6; ++i) r.stage_us[i] += stages[i];
  ++r.stage_frames;
  if (frame.last_event_seq() <= acknowledged) return;
  // This frame is the first to apply every event since the last acknowledged one.
  for (std::uint64_t seq = acknowledged + 1; seq <= frame.last_event_seq(); ++seq) {
    r.latency_ms.push_back(std::chrono::duration<double, std::milli>(now - stream.SentAt(seq)).count());
  }
  const double latency_us = r.latency_ms.back() * 1000.0;
  r.stage_us[6] += std::max(0.0, latency_us - double(t.server_us()));
  ++r.transfer_frames;
  acknowledged = frame.last_event_seq();
}

SessionResult RunSession(const LoadtestOptions& o, Client& client, const v1::VolumeInfo& volume, int index) {
  SessionResult r;
  try {
    v1::CreateSessionRequest request;
    request.set_volume_id(volume.id());
    request.mutable_viewport()->set_width(o.width);
    request.mutable_viewport()->set_height(o.height);
    if (o.scene.empty()) {
      request.set_preset(o.preset);
    } else {
      *request.mutable_scene() = LoadSceneFile(o.scene);
    }
    request.mutable_stream()->set_denoiser(ParseDenoiser(o.denoiser));
    request.mutable_stream()->set_jpeg_quality(o.jpeg_quality);
    const auto created = client.CreateSession(request);
    r.id = created.session_id();
    auto stream = client.Attach(r.id);
    v1::SessionEvent spp;
    spp.mutable_render()->set_spp(o.spp);
    stream->Send(spp);

    const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / o.event_hz));
    const Clock::time_point start = Clock::now();
    const Clock::time_point end = start + std::chrono::duration_cast<Clock::duration>(
                                              std::chrono::duration<double>(o.seconds));
    Clock::time_point next_event = start;
    std::uint64_t acknowledged = 0, last_frame_id = 0;
    double angle = 37.0 * index;  // sessions look at different sides
    while (Clock::now() < end && !stream->ended()) {
      if (Clock::now() >= next_event) {
        v1::SessionEvent e;
        *e.mutable_camera() = OrbitCamera(volume, angle += o.degrees_per_event);
        if (stream->Send(e)) ++r.events;
        next_event += period;
      }
      const auto wait = std::chrono::duration_cast<std::chrono::milliseconds>(
          std::min(next_event, end) - Clock::now());
      auto message = stream->Next(std::max(wait, std::chrono::milliseconds(0)));
      if (!message || !message->has_frame()) continue;
      const v1::Frame& f = message->frame();
      if (last_frame_id > 0 && f.frame_id() > last_frame_id + 1) r.dropped += f.frame_id() - last_frame_id - 1;
      last_frame_id = f.frame_id();
      AddFrame(f, Clock::now(), *stream, acknowledged, r);
    }
    r.seconds = std::chrono::duration<double>(Clock::now() - start).count();
    if (stream->ended() && !stream->status().ok()) throw RpcError(stream->status());
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
  double fps_min = INFINITY, fps_mean = 0, fps_total = 0;
  std::vector<double> latencies;
  std::uint64_t frames = 0, bytes = 0, dropped = 0;
  std::array<double, 7> stage_ms{};
  std::map<std::string, int> errors;
};

Summary Summarise(const std::vector<SessionResult>& results) {
  Summary s;
  std::array<double, 7> sums{};
  std::uint64_t stage_frames = 0, transfer_frames = 0;
  for (const SessionResult& r : results) {
    if (!r.error.empty()) ++s.errors[r.error];
    const double fps = r.seconds > 0 ? r.frames / r.seconds : 0;
    s.fps_min = std::min(s.fps_min, fps);
    s.fps_total += fps;
    s.latencies.insert(s.latencies.end(), r.latency_ms.begin(), r.latency_ms.end());
    s.frames += r.frames;
    s.bytes += r.bytes;
    s.dropped += r.dropped;
    for (int i = 0; i < 7; ++i) sums[i] += r.stage_us[i];
    stage_frames += r.stage_frames;
    transfer_frames += r.transfer_frames;
  }
  s.fps_mean = results.empty() ? 0 : s.fps_total / double(results.size());
  for (int i = 0; i < 7; ++i) {
    const std::uint64_t n = i == 6 ? transfer_frames : stage_frames;
    s.stage_ms[i] = n ? sums[i] / double(n) / 1000.0 : NAN;
  }
  return s;
}

std::string Table(const LoadtestOptions& o, const std::string& device, const std::vector<SessionResult>& results,
                  const Summary& s) {
  std::string t = fmt::format(
      "cinevol loadtest: {} session(s) x {:.0f} s on {} ({}), {}x{}, {} spp, {}, camera events at {:.0f} Hz\n\n"
      "| session | frames | fps | latency p50 ms | p95 ms | p99 ms | MB | dropped | error |\n"
      "|---|---|---|---|---|---|---|---|---|\n",
      o.sessions, o.seconds, o.server, device, o.width, o.height, o.spp, o.denoiser, o.event_hz);
  for (const SessionResult& r : results) {
    t += fmt::format("| {} | {} | {:.1f} | {:.1f} | {:.1f} | {:.1f} | {:.1f} | {} | {} |\n", r.id, r.frames,
                     r.seconds > 0 ? r.frames / r.seconds : 0, Percentile(r.latency_ms, 0.5),
                     Percentile(r.latency_ms, 0.95), Percentile(r.latency_ms, 0.99), r.bytes / 1e6, r.dropped,
                     r.error.empty() ? "-" : r.error);
  }
  t += fmt::format("| all | {} | {:.1f} (min {:.1f}, total {:.1f}) | {:.1f} | {:.1f} | {:.1f} | {:.1f} | {} | {} |\n\n",
                   s.frames, s.fps_mean, s.fps_min, s.fps_total, Percentile(s.latencies, 0.5),
                   Percentile(s.latencies, 0.95), Percentile(s.latencies, 0.99), s.bytes / 1e6, s.dropped,
                   s.errors.size());
  t += "mean per frame, ms:";
  for (int i = 0; i < 7; ++i) t += fmt::format(" {} {:.2f}{}", kStageNames[i], s.stage_ms[i], i < 6 ? "," : "\n");
  t += "(queue: event arrival to render start; server: event arrival to send start; transfer: the rest of the "
       "latency, i.e. send, network and client)\n";
  for (const SessionResult& r : results) {
    if (!r.error.empty()) t += fmt::format("session {}: {}\n", r.id.empty() ? "?" : r.id, r.error_message);
  }
  return t;
}

std::string Json(const LoadtestOptions& o, const std::string& device, const std::vector<SessionResult>& results,
                 const Summary& s) {
  auto number = [](double v) { return std::isfinite(v) ? fmt::format("{:.3f}", v) : std::string("null"); };
  std::string j = fmt::format(
      "{{\"server\": \"{}\", \"device\": \"{}\", \"sessions\": {}, \"seconds\": {}, \"width\": {}, \"height\": {}, "
      "\"spp\": {}, \"denoiser\": \"{}\", \"event_hz\": {},\n \"per_session\": [",
      o.server, device, o.sessions, o.seconds, o.width, o.height, o.spp, o.denoiser, o.event_hz);
  for (std::size_t i = 0; i < results.size(); ++i) {
    const SessionResult& r = results[i];
    j += fmt::format("{}\n  {{\"id\": \"{}\", \"frames\": {}, \"fps\": {}, \"latency_ms\": {{\"p50\": {}, \"p95\": {}, "
                     "\"p99\": {}}}, \"bytes\": {}, \"dropped\": {}, \"error\": \"{}\"}}",
                     i ? "," : "", r.id, r.frames, number(r.seconds > 0 ? r.frames / r.seconds : 0),
                     number(Percentile(r.latency_ms, 0.5)), number(Percentile(r.latency_ms, 0.95)),
                     number(Percentile(r.latency_ms, 0.99)), r.bytes, r.dropped, r.error);
  }
  j += fmt::format("],\n \"overall\": {{\"frames\": {}, \"fps_mean\": {}, \"fps_min\": {}, \"fps_total\": {}, "
                   "\"latency_ms\": {{\"p50\": {}, \"p95\": {}, \"p99\": {}}}, \"bytes\": {}, \"dropped\": {}, "
                   "\"stage_ms\": {{",
                   s.frames, number(s.fps_mean), number(s.fps_min), number(s.fps_total),
                   number(Percentile(s.latencies, 0.5)), number(Percentile(s.latencies, 0.95)),
                   number(Percentile(s.latencies, 0.99)), s.bytes, s.dropped);
  for (int i = 0; i < 7; ++i) j += fmt::format("{}\"{}\": {}", i ? ", " : "", kStageNames[i], number(s.stage_ms[i]));
  j += "}, \"errors\": {";
  bool first = true;
  for (const auto& [code, n] : s.errors) {
    j += fmt::format("{}\"{}\": {}", first ? "" : ", ", code, n);
    first = false;
  }
  return j + "}}}\n";
}

int Run(const LoadtestOptions& o) {
  Client client({.address = o.server});
  v1::VolumeInfo volume;
  const std::vector<v1::VolumeInfo> volumes = client.ListVolumes();
  if (o.volume.empty()) {
    if (volumes.empty()) throw RpcError({grpc::StatusCode::NOT_FOUND, "the server holds no volume"});
    volume = volumes.front();
  } else {
    volume = client.DescribeVolume(o.volume);
  }
  const v1::ServerStatus status = client.Status();
  std::string device;
  for (const v1::DeviceStatus& d : status.devices()) device += (device.empty() ? "" : ", ") + d.name();

  std::vector<SessionResult> results(o.sessions);
  std::vector<std::thread> threads;
  for (int i = 0; i < o.sessions; ++i) {
    threads.emplace_back([&, i] { results[i] = RunSession(o, client, volume, i); });
  }
  for (std::thread& t : threads) t.join();
  const Summary summary = Summarise(results);
  const std::string report = o.json ? Json(o, device, results, summary) : Table(o, device, results, summary);
  std::fputs(report.c_str(), stdout);
  if (!o.out.empty()) std::ofstream(o.out, std::ios::app) << report;
  return summary.errors.empty() ? 0 : 1;
}

}  // namespace

void AddLoadtestCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("loadtest", "Concurrent orbiting sessions against a server: fps, latency, errors");
  auto o = std::make_shared<LoadtestOptions>();
  cmd->add_option("--server", o->server, "Server address HOST:PORT")->capture_default_str();
  cmd->add_option("--sessions", o->sessions, "Concurrent sessions")->check(CLI::Range(1, 1024))->capture_default_str();
  cmd->add_option("--seconds", o->seconds, "How long each session runs")->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
  cmd->add_option("--width", o->width, "Viewport width")->check(CLI::Range(1, 8192))->capture_default_str();
  cmd->add_option("--height", o->height, "Viewport height")->check(CLI::Range(1, 8192))->capture_default_str();
  cmd->add_option("--spp", o->spp, "Samples per pixel per frame")->check(CLI::Range(1, 256))->capture_default_str();
  cmd->add_option("--denoiser", o->denoiser, "none, accumulate, knn, guided, svgf or wrls")
      ->check(CLI::IsMember({"none", "accumulate", "knn", "guided", "svgf", "wrls"}))
      ->capture_default_str();
  cmd->add_option("--volume", o->volume, "Volume id (default: the server's first)");
  cmd->add_option("--preset", o->preset, "Transfer-function preset")->capture_default_str();
  cmd->add_option("--scene", o->scene, "Start from this scene file's transfer function and lights instead");
  cmd->add_option("--event-hz", o->event_hz, "Camera events per second per session")->check(CLI::Range(0.1, 10000.0))
      ->capture_default_str();
  cmd->add_option("--jpeg-quality", o->jpeg_quality, "JPEG quality")->check(CLI::Range(1, 100))->capture_default_str();
  cmd->add_flag("--json", o->json, "Print JSON instead of a table");
  cmd->add_option("--out", o->out, "Also append the report to this file");
  cmd->callback([o] {
    if (Run(*o) != 0) throw CLI::RuntimeError(1);
  });
}

}  // namespace cinevol::cli

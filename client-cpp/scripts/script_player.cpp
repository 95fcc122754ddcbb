// Play: the send/receive loop and its measurements.
#include "script_player.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <regex>

namespace cinevol::cli {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

// The server names a bad event by its sequence number; the user knows its line.
std::string ExplainStatus(const grpc::Status& status, const std::map<std::uint64_t, int>& line_of_seq) {
  std::smatch m;
  const std::string text = status.error_message();
  if (std::regex_search(text, m, std::regex("^event ([0-9]+): "))) {
    const auto it = line_of_seq.find(std::stoull(m[1]));
    if (it != line_of_seq.end() && it->second > 0)
      return fmt::format("script line {}: {}", it->second, m.suffix().str());
  }
  return text;
}

void AddFrame(const v1::Frame& f, SessionStream& stream, Clock::time_point now, std::uint64_t& answered,
              std::uint64_t& last_id, PlayResult& r, double& latency_ms) {
  ++r.frames;
  r.bytes += EncodedImage(f).size();
  if (f.resolution_scale() > 0 && f.resolution_scale() < 1) ++r.smaller_frames;
  if (last_id > 0 && f.frame_id() > last_id + 1) r.dropped += f.frame_id() - last_id - 1;
  last_id = std::max(last_id, f.frame_id());
  const auto& t = f.timings();
  const double stages[] = {double(t.render_us()), double(t.denoise_us()), double(t.tonemap_us()),
                           double(t.encode_us()), double(t.queue_us()),   double(t.server_us())};
  for (int i = 0; i < 6; ++i) r.stage_us_sum[i] += stages[i];
  ++r.stage_frames;
  latency_ms = 0;
  if (f.last_event_seq() <= answered) return;
  for (std::uint64_t seq = answered + 1; seq <= f.last_event_seq(); ++seq) {
    const Clock::time_point sent = stream.SentAt(seq);
    if (sent != Clock::time_point{})
      r.latency_ms.push_back(std::chrono::duration<double, std::milli>(now - sent).count());
  }
  answered = f.last_event_seq();
  if (r.latency_ms.empty()) return;
  latency_ms = r.latency_ms.back();
  r.stage_us_sum[6] += std::max(0.0, latency_ms * 1000.0 - t.server_us());
  ++r.transfer_frames;
}

}  // namespace

double PlayResult::StageMs(int stage) const {
  const std::uint64_t n = stage == 6 ? transfer_frames : stage_frames;
  return n ? stage_us_sum[stage] / double(n) / 1000.0 : NAN;
}

v1::VolumeInfo ResolveVolume(Client& client, const std::string& id) {
  if (!id.empty()) return client.DescribeVolume(id);
  const std::vector<v1::VolumeInfo> volumes = client.ListVolumes();
  if (volumes.empty()) throw RpcError({grpc::StatusCode::NOT_FOUND, "the server holds no volume"});
  return volumes.front();
}

v1::VolumeInfo ResolveVolume(Client& client, const ScriptSession& session) {
  const v1::VolumeInfo volume = !session.upload.empty() ? client.UploadVolume(session.upload)
                                : !session.load.empty() ? client.LoadVolume(session.load)
                                : session.series        ? client.LoadSeries(*session.series)
                                                        : ResolveVolume(client, session.volume);
  const ScriptLabels& labels = session.labels;
  if (labels.empty()) return volume;
  return labels.upload.empty() ? client.LoadLabels(volume.id(), labels.load, labels.server_table)
                               : client.UploadLabels(volume.id(), labels.upload, labels.local_table);
}

double Percentile(std::vector<double> v, double p) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(p * double(v.size())))];
}

PlayResult Play(SessionStream& stream, const std::vector<ScriptStep>& steps, const PlayOptions& o,
                const std::function<void(const ReceivedFrame&)>& on_frame,
                const std::function<void(const PlayResult&)>& every_second) {
  PlayResult r;
  std::map<std::uint64_t, int> line_of_seq;
  const Clock::time_point start = Clock::now();
  // A looped timeline restarts after its last step, and at most once a second.
  const double period = steps.empty() ? 0 : std::max(steps.back().at, 1.0);
  std::size_t next = 0;
  double lap = 0;  // timeline offset of the current loop
  std::uint64_t answered = 0, last_id = 0, last_sent = 0;
  std::uint64_t applied = 0;  // the newest event a frame or a state answered
  bool final_after_last = false;
  int resumes = stream.resumes();
  double next_report = 1;
  for (;;) {
    const double now = SecondsSince(start);
    if (now >= o.max_seconds || stream.ended()) break;
    if (next == steps.size() && !o.loop && (!o.wait_final || final_after_last)) break;
    if (next == steps.size() && o.loop && !steps.empty()) {
      next = 0;
      lap += period;
    }
    // Send every step that is due; a call waits until the events before it are applied.
    bool call_waits = false;  // a due call waits for a frame or state that answers them
    while (next < steps.size() && lap + steps[next].at <= now) {
      if (!steps[next].ui.empty() || (steps[next].call && !o.on_call)) {  // nothing to send
        ++next;
        continue;
      }
      if (steps[next].call) {
        call_waits = applied < last_sent;
        if (call_waits) break;
        o.on_call(steps[next++]);
        continue;
      }
      if (const std::uint64_t seq = stream.Send(steps[next].event)) {
        line_of_seq[seq] = steps[next].line;
        last_sent = seq;
        final_after_last = false;
        ++r.events;
      }
      ++next;
    }
    if (stream.resumes() != resumes) {  // a new connection numbers events from 1 again
      resumes = stream.resumes();
      answered = last_sent = applied = 0;
      line_of_seq.clear();
    }
    const double next_at = next < steps.size() && !call_waits ? lap + steps[next].at : o.max_seconds;
    const double until = std::min({o.max_seconds, next_at, next_report});
    const auto wait = std::chrono::duration<double>(std::max(0.0, until - SecondsSince(start)));
    auto message = stream.Next(std::chrono::duration_cast<std::chrono::milliseconds>(wait));
    if (message && message->has_state()) applied = std::max(applied, message->state().last_event_seq());
    if (message && message->has_frame()) {
      applied = std::max(applied, message->frame().last_event_seq());
      const v1::Frame& f = message->frame();
      double latency = 0;
      AddFrame(f, stream, Clock::now(), answered, last_id, r, latency);
      if (f.final() && f.last_event_seq() >= last_sent) final_after_last = true;
      if (on_frame) on_frame({f, SecondsSince(start), latency});
    }
    if (SecondsSince(start) >= next_report) {
      r.seconds = SecondsSince(start);
      if (every_second) every_second(r);
      next_report += 1;
    }
  }
  r.seconds = SecondsSince(start);
  if (stream.ended()) {
    r.status = stream.status();
    if (!r.status.ok()) r.error = ExplainStatus(r.status, line_of_seq);
  }
  return r;
}

}  // namespace cinevol::cli

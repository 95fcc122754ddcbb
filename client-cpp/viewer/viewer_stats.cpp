// The viewer's own measurements.
#include "viewer/viewer_stats.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "script_player.h"

namespace cinevol::viewer {

void ViewerStats::Age() {
  const Clock::time_point now = Clock::now();
  while (!displayed.empty() && now - displayed.front() > std::chrono::seconds(1)) displayed.pop_front();
  while (!bytes.empty() && now - bytes.front().first > std::chrono::seconds(1)) bytes.pop_front();
}

void ViewerStats::Shown(const ViewFrame& frame, const Connection& connection) {
  const Clock::time_point now = Clock::now();
  const v1::Frame& f = frame.info;
  if (last_frame_id > 0 && f.frame_id() > last_frame_id + 1) dropped += f.frame_id() - last_frame_id - 1;
  for (std::uint64_t seq = last.last_event_seq() + 1; seq <= f.last_event_seq(); ++seq) {
    if (const auto sent = connection.SentAt(seq)) {
      latency_ms.push_back(std::chrono::duration<double, std::milli>(now - *sent).count());
      if (whole_run_) all_latency_ms_.push_back(latency_ms.back());
    }
  }
  while (latency_ms.size() > 200) latency_ms.pop_front();
  last_frame_id = f.frame_id();
  last = f;
  displayed.push_back(now);
  last_shown = now;
  bytes.emplace_back(now, frame.image_bytes);
  decode_ms = frame.decode_ms;
  if (whole_run_) all_decode_ms_.push_back(frame.decode_ms);
  all_bytes_ += frame.image_bytes;
}

void ViewerStats::TurnTook(double loop_ms) {
  draw_ms = loop_ms - upload_ms;
  if (whole_run_) all_ui_ms_.push_back(loop_ms);
}

double ViewerStats::LatencyPercentile(double q) const {
  if (latency_ms.empty()) return NAN;
  std::vector<double> v(latency_ms.begin(), latency_ms.end());
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(q * double(v.size())))];
}

double ViewerStats::BytesPerSecond() const {
  double sum = 0;
  for (const auto& [at, n] : bytes) sum += double(n);
  return sum;
}

void ViewerStats::PrintSummary(double seconds, const std::string& renderer, const std::string& video_driver) const {
  std::printf(
      "cinevol-viewer: %zu frames shown in %.1f s (%.1f fps), %.2f MB/s; event-to-frame latency p50/p95 %.1f/%.1f ms "
      "over %zu events; per frame shown: decode p50/p95 %.2f/%.2f ms (decoder thread), upload and draw p50/p95 "
      "%.2f/%.2f ms (UI thread, SDL renderer %s, video driver %s)\n",
      all_ui_ms_.size(), seconds, seconds > 0 ? double(all_ui_ms_.size()) / seconds : 0.0,
      seconds > 0 ? double(all_bytes_) / seconds / 1e6 : 0.0, cli::Percentile(all_latency_ms_, 0.5),
      cli::Percentile(all_latency_ms_, 0.95), all_latency_ms_.size(), cli::Percentile(all_decode_ms_, 0.5),
      cli::Percentile(all_decode_ms_, 0.95), cli::Percentile(all_ui_ms_, 0.5), cli::Percentile(all_ui_ms_, 0.95),
      renderer.c_str(), video_driver.c_str());
  std::fflush(stdout);
}

}  // namespace cinevol::viewer

// What the viewer measures of itself and the stream: for the stats overlay
// (F2), and the summary a script run prints at its end (docs/viewer.md).
#pragma once

#include <cstdint>
#include <deque>
#include <string>
#include <utility>
#include <vector>

#include "viewer/connection.h"
#include "viewer/viewer_context.h"

namespace cinevol::viewer {

struct ViewerStats {
  explicit ViewerStats(bool whole_run) : whole_run_(whole_run) {}

  // A frame reached the screen: its rate, size, latency (from the events it answers) and cost.
  void Shown(const ViewFrame& frame, const Connection& connection);
  // Drops what is older than a second (the overlay's window); once a turn.
  void Age();
  // The UI thread's cost of a frame shown: upload, panels, drawing, present.
  void TurnTook(double loop_ms);
  void StartOver() { last_frame_id = 0; }  // a new session: a script's settle waits for its first frame

  double Fps() const { return double(displayed.size()); }
  double LatencyPercentile(double q) const;
  double BytesPerSecond() const;
  // The run's summary line: frames, rate, latency, costs.
  void PrintSummary(double seconds, const std::string& renderer, const std::string& video_driver) const;

  std::deque<Clock::time_point> displayed;                      // frames shown in the last second
  std::deque<double> latency_ms;                                // event-to-frame, the last 200 events
  std::deque<std::pair<Clock::time_point, std::size_t>> bytes;  // the last second
  std::uint64_t last_frame_id = 0, dropped = 0;
  double decode_ms = 0, upload_ms = 0, draw_ms = 0;  // the viewer's own cost, last frame
  v1::Frame last;                                    // the newest frame's header
  Clock::time_point last_shown;                      // when it arrived

 private:
  // Over the whole run, for the summary (kept only when a script runs: a
  // viewer left open would grow them for ever).
  bool whole_run_;
  std::vector<double> all_decode_ms_, all_ui_ms_, all_latency_ms_;  // ui: upload and draw on the UI thread
  std::size_t all_bytes_ = 0;
};

}  // namespace cinevol::viewer

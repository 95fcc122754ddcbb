// Plays a script's timeline on an attached session stream: sends each step's
// event at its time, takes every frame the server sends, and measures frame
// rate, event-to-frame latency (an event's send to the receipt of the first
// frame that applied it), bytes, dropped frames and the server's stage times.
// `cinevol play`, `demo` and `loadtest` all play through it.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "client.h"
#include "session_script.h"

namespace cinevol::cli {

struct PlayOptions {
  double max_seconds = 60;  // the run never lasts longer
  bool loop = false;        // repeat the timeline (every max(last step's time, 1 s)) until max_seconds
  bool wait_final = true;   // after the last step, wait for the frame that ends refinement
  // Makes a step's reading call ("slice" and "pick" lines, ScriptStep::call)
  // once the server has applied every event sent before it (a frame or a
  // state answered them), on the playing thread. Unset: such steps are skipped.
  std::function<void(const ScriptStep&)> on_call;
};

struct ReceivedFrame {
  const v1::Frame& frame;
  double at = 0;          // seconds since the start
  double latency_ms = 0;  // for the newest event it is the first to apply; 0 when it answers none
};

// Stages in FrameTimings order, then transfer (latency minus the server's share).
inline constexpr const char* kStageNames[] = {"render", "denoise", "tonemap", "encode", "queue", "server", "transfer"};

struct PlayResult {
  std::uint64_t frames = 0, bytes = 0, dropped = 0, events = 0;
  std::uint64_t smaller_frames = 0;  // rendered at a resolution scale below 1 (interactive resolution)
  double seconds = 0;
  std::vector<double> latency_ms;  // one per event a frame answered
  std::array<double, 7> stage_us_sum{};
  std::uint64_t stage_frames = 0, transfer_frames = 0;
  grpc::Status status;  // how the stream ended; OK while it lasted the run
  std::string error;    // the status's message, with "event N" told as the script line it came from

  double fps() const { return seconds > 0 ? frames / seconds : 0; }
  double StageMs(int stage) const;
};

PlayResult Play(SessionStream& stream, const std::vector<ScriptStep>& steps, const PlayOptions& options,
                const std::function<void(const ReceivedFrame&)>& on_frame = {},
                const std::function<void(const PlayResult&)>& every_second = {});

// The volume `id` names, or the server's first when `id` is empty.
v1::VolumeInfo ResolveVolume(Client& client, const std::string& id);
// The volume a script's session line names: its upload or load, done now,
// else its volume id as above.
v1::VolumeInfo ResolveVolume(Client& client, const ScriptSession& session);

// The p-quantile (0..1) of `values`; NaN when empty.
double Percentile(std::vector<double> values, double p);

}  // namespace cinevol::cli

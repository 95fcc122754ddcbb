// Requests, waits and image comparisons shared by the service tests.
#pragma once

#include <chrono>
#include <cmath>
#include <functional>
#include <optional>
#include <string>

#include "client.h"
#include "core/image.h"
#include "encode/image_codecs.h"

namespace cinevol::testing {

// A small CPU-friendly session on the server's phantom.
inline v1::CreateSessionRequest SmallSession(const std::string& preset = "ct-bone", int width = 96, int height = 64,
                                             int target_spp = 16) {
  v1::CreateSessionRequest r;
  r.set_volume_id("phantom:head?size=48");
  r.mutable_viewport()->set_width(width);
  r.mutable_viewport()->set_height(height);
  r.set_preset(preset);
  r.mutable_stream()->set_target_spp(target_spp);
  return r;
}

// The first frame that satisfies `want`, waiting at most `timeout` in all.
inline std::optional<v1::Frame> WaitFrame(SessionStream& stream, const std::function<bool(const v1::Frame&)>& want,
                                          std::chrono::milliseconds timeout = std::chrono::seconds(60)) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    auto message = stream.Next(std::chrono::milliseconds(200));
    if (!message) {
      if (stream.ended()) return std::nullopt;
      continue;
    }
    if (message->has_frame() && want(message->frame())) return message->frame();
  }
  return std::nullopt;
}

// The frame that ends refinement after event `seq` (0: after none).
inline std::optional<v1::Frame> WaitFinal(SessionStream& stream, std::uint64_t seq = 0) {
  return WaitFrame(stream, [seq](const v1::Frame& f) { return f.final() && f.last_event_seq() >= seq; });
}

inline ImageRgb8 Decode(const v1::Frame& frame) {
  return DecodeJpeg(std::vector<std::uint8_t>(frame.jpeg().begin(), frame.jpeg().end()));
}

// Mean absolute difference per channel, in 8-bit levels.
inline double MeanAbsDiff(const ImageRgb8& a, const ImageRgb8& b) {
  if (a.bytes.size() != b.bytes.size() || a.bytes.empty()) return INFINITY;
  double sum = 0;
  for (std::size_t i = 0; i < a.bytes.size(); ++i) sum += std::abs(int(a.bytes[i]) - int(b.bytes[i]));
  return sum / double(a.bytes.size());
}

inline double MeanLevel(const ImageRgb8& a) {
  double sum = 0;
  for (std::uint8_t v : a.bytes) sum += v;
  return a.bytes.empty() ? 0 : sum / double(a.bytes.size());
}

// The status of session `id` on the server, if it still holds it.
inline std::optional<v1::SessionStatus> FindSessionStatus(Client& client, const std::string& id) {
  const v1::ServerStatus status = client.Status();
  for (const v1::SessionStatus& s : status.sessions()) {
    if (s.session_id() == id) return s;
  }
  return std::nullopt;
}

// Polls `condition` every 50 ms for up to `timeout`.
inline bool Eventually(const std::function<bool()>& condition, std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    if (condition()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return condition();
}

}  // namespace cinevol::testing

// Requests, waits and image comparisons shared by the service tests.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <thread>
#include <functional>
#include <optional>
#include <string>

#include <gtest/gtest.h>

#include "client.h"
#include "core/image.h"
#include "encode/image_codecs.h"

namespace cinevol::testing {

using namespace std::chrono_literals;

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

// Runs `call` and expects it to throw RpcError with `code` and `text` in its message.
template <class F>
void ExpectRpcError(F&& call, grpc::StatusCode code, const std::string& text) {
  try {
    call();
    ADD_FAILURE() << "no error; expected " << StatusCodeName(code) << " naming '" << text << "'";
  } catch (const RpcError& e) {
    EXPECT_EQ(e.code(), code) << e.what();
    EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what();
  }
}

// The samples per pixel at which a still of `session` takes about `seconds`
// on this server, from the time of smaller ones (machines and their load
// differ; a test that needs a still longer than some limit asks for this).
// The probes grow until one takes a tenth of `seconds`: on many cores a
// small still's fixed costs would pass for its samples' and make the still
// several times too short.
inline int SppForSeconds(Client& client, const std::string& session, double seconds) {
  v1::SnapshotRequest probe;
  probe.set_session_id(session);
  int spp = 8;
  double per_spp = 0;
  for (int i = 0; i < 4; ++i) {
    probe.set_spp(spp);
    const double taken = client.Snapshot(probe).render_us() * 1e-6;
    per_spp = std::max(1e-6, taken / spp);
    if (taken >= 0.1 * seconds || spp >= 2048) break;
    spp = std::min(2048, int(spp * std::clamp(0.15 * seconds / std::max(taken, 1e-4), 2.0, 16.0)));
  }
  return std::clamp(int(seconds / per_spp), 16, 16384);
}

// A 16^3 NRRD volume of 16-bit values, written to `path`.
inline void WriteSmallNrrd(const std::filesystem::path& path) {
  std::ofstream out(path, std::ios::binary);
  out << "NRRD0004\ntype: short\ndimension: 3\nsizes: 16 16 16\nspacings: 1 1 1\nencoding: raw\nendian: little\n\n";
  for (int i = 0; i < 16 * 16 * 16; ++i) {
    const std::int16_t v = static_cast<std::int16_t>((i % 16) * 100);
    out.write(reinterpret_cast<const char*>(&v), sizeof v);
  }
}

// The server must still create sessions and stream frames.
inline void ExpectServing(Client& client) {
  const auto created = client.CreateSession(SmallSession());
  auto stream = client.Attach(created.session_id());
  EXPECT_TRUE(WaitFrame(*stream, [](const v1::Frame&) { return true; }, 30s)) << "the server stopped serving";
  client.CloseSession(created.session_id());
}

// A camera step of an orbit around the phantom.
inline v1::SessionEvent Orbit(int step) {
  v1::SessionEvent e;
  v1::Camera* c = e.mutable_camera();
  c->mutable_eye()->set_x(float(200 * std::sin(step * 0.05)));
  c->mutable_eye()->set_y(float(-200 * std::cos(step * 0.05)));
  c->mutable_target();
  c->mutable_up()->set_z(1);
  return e;
}

// Frames per second a normally reading session gets over `seconds`, sending
// camera events at 60 Hz.
inline double ReadingFps(SessionStream& stream, std::chrono::milliseconds duration) {
  while (stream.Next(0ms)) {  // frames that arrived before the measurement
  }
  int frames = 0, step = 0;
  const auto start = std::chrono::steady_clock::now();
  auto next = start;
  while (std::chrono::steady_clock::now() - start < duration) {
    if (std::chrono::steady_clock::now() >= next) {
      stream.Send(Orbit(step++));
      next += 16ms;
    }
    if (auto m = stream.Next(5ms); m && m->has_frame()) ++frames;
  }
  return frames / std::chrono::duration<double>(duration).count();
}

// A neighbour that reads normally on a thread of its own (ReadingFps's
// camera events at 60 Hz) while a test attacks the server: its frames per
// second and the longest gap between two of its frames, taken when it stops.
class Witness {
 public:
  struct Report {
    double fps = 0;
    double longest_gap_s = 0;
  };
  explicit Witness(SessionStream& stream) : stream_(stream), thread_([this] { Read(); }) {}
  ~Witness() { Stop(); }
  Witness(const Witness&) = delete;
  Witness& operator=(const Witness&) = delete;

  // Ends the reading (at once; the test's own limits bound what it waited on).
  Report Stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
    return report_;
  }

 private:
  void Read() {
    while (stream_.Next(0ms)) {  // frames that arrived before the measurement
    }
    int frames = 0, step = 0;
    const auto start = std::chrono::steady_clock::now();
    auto next = start, last_frame = start;
    while (!stop_ && std::chrono::steady_clock::now() - start < 600s) {
      const auto now = std::chrono::steady_clock::now();
      if (now >= next) {
        stream_.Send(Orbit(step++));
        next += 16ms;
      }
      if (auto m = stream_.Next(5ms); m && m->has_frame()) {
        const auto at = std::chrono::steady_clock::now();
        report_.longest_gap_s = std::max(report_.longest_gap_s, std::chrono::duration<double>(at - last_frame).count());
        last_frame = at;
        ++frames;
      }
    }
    const auto end = std::chrono::steady_clock::now();
    report_.longest_gap_s = std::max(report_.longest_gap_s, std::chrono::duration<double>(end - last_frame).count());
    report_.fps = frames / std::max(1e-3, std::chrono::duration<double>(end - start).count());
  }

  SessionStream& stream_;
  std::atomic<bool> stop_{false};
  Report report_;
  std::thread thread_;
};

}  // namespace cinevol::testing

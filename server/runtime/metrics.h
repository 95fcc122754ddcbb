// Prometheus metrics of cinevol-server, served on /metrics when
// --metrics-listen HOST:PORT is given. One process-wide instance
// (ServerMetrics()) that the service's code updates with small calls; label
// values come from bounded sets only (stages, states, status codes, limit
// flags, devices): never session ids, paths, principals or volume ids.
#pragma once

#include <grpcpp/support/status_code_enum.h>
#include <prometheus/counter.h>
#include <prometheus/family.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/registry.h>

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>

namespace cinevol::service {

enum class Stage { kRender, kDenoise, kTonemap, kEncode, kSend };

// Sessions by state, as ServerStatus reports them.
struct SessionStates {
  int starting = 0, rendering = 0, idle = 0, paused = 0, detached = 0;
};

// "INVALID_ARGUMENT", "NOT_FOUND", ...
const char* StatusCodeLabel(grpc::StatusCode code);

class Metrics {
 public:
  Metrics();

  const std::shared_ptr<prometheus::Registry>& registry() const { return registry_; }

  void FrameRendered() { frames_rendered_.Increment(); }
  // A frame's JPEG reached the transport: its bytes, and StartWrite to OnWriteDone.
  void FrameSent(std::uint64_t bytes, double send_seconds);
  // A frame rendered and encoded that never went out (replaced or stale).
  void FrameDropped() { frames_dropped_.Increment(); }
  void EventReceived() { events_received_.Increment(); }
  void EventCoalesced() { events_coalesced_.Increment(); }
  void ObserveStage(Stage stage, double seconds);
  void Upload(bool ok) { (ok ? uploads_ok_ : uploads_error_).Increment(); }
  // How a reader child ended (io/reader_cage.h's outcomes: "ok", "refused",
  // "crashed", "sandbox", "memory", "cpu", "timeout", "cancelled", "protocol").
  void ReaderEnded(std::string_view outcome);
  // A LimitExceeded, by its flag ("max-lights").
  void LimitRefused(const std::string& flag);
  // A non-OK status a caller gets.
  void Error(grpc::StatusCode code);

  // Set by the server's sweeper.
  void SetSessions(const SessionStates& states);
  void SetVolumeMemory(std::uint64_t bytes) { volume_memory_.Set(double(bytes)); }
  void SetDeviceMemoryUsed(int gpu, std::uint64_t bytes);
  // The accept guard's running total (ShedConnections()).
  void SetConnectionsShed(std::uint64_t total);

 private:
  std::shared_ptr<prometheus::Registry> registry_;
  prometheus::Family<prometheus::Gauge>& sessions_family_;
  prometheus::Gauge &starting_, &rendering_, &idle_, &paused_, &detached_;
  prometheus::Counter& frames_sent_;
  prometheus::Counter& frames_dropped_;
  prometheus::Counter& frames_rendered_;
  prometheus::Counter& events_received_;
  prometheus::Counter& events_coalesced_;
  prometheus::Family<prometheus::Histogram>& stage_family_;
  prometheus::Histogram &render_, &denoise_, &tonemap_, &encode_, &send_;
  prometheus::Counter& sent_bytes_;
  prometheus::Family<prometheus::Gauge>& device_memory_family_;
  prometheus::Gauge& volume_memory_;
  prometheus::Family<prometheus::Counter>& uploads_family_;
  prometheus::Counter &uploads_ok_, &uploads_error_;
  prometheus::Family<prometheus::Counter>& limit_refusals_family_;
  prometheus::Family<prometheus::Counter>& reader_outcomes_family_;
  prometheus::Family<prometheus::Counter>& errors_family_;
  prometheus::Counter& connections_shed_;

  std::mutex mu_;
  std::uint64_t shed_seen_ = 0;
};

// The process's metrics (lives as long as the process).
Metrics& ServerMetrics();

}  // namespace cinevol::service

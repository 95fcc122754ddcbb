// Metrics: the families, their series, and the small updates.
#include "runtime/metrics.h"

#include <fmt/format.h>

namespace cinevol::service {
namespace {

using prometheus::BuildCounter;
using prometheus::BuildGauge;
using prometheus::BuildHistogram;

// 0.1 ms .. 10 s, about three buckets a decade.
const prometheus::Histogram::BucketBoundaries& StageBuckets() {
  static const prometheus::Histogram::BucketBoundaries buckets{
      0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10};
  return buckets;
}

}  // namespace

const char* StatusCodeLabel(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::OK: return "OK";
    case grpc::StatusCode::CANCELLED: return "CANCELLED";
    case grpc::StatusCode::UNKNOWN: return "UNKNOWN";
    case grpc::StatusCode::INVALID_ARGUMENT: return "INVALID_ARGUMENT";
    case grpc::StatusCode::DEADLINE_EXCEEDED: return "DEADLINE_EXCEEDED";
    case grpc::StatusCode::NOT_FOUND: return "NOT_FOUND";
    case grpc::StatusCode::ALREADY_EXISTS: return "ALREADY_EXISTS";
    case grpc::StatusCode::PERMISSION_DENIED: return "PERMISSION_DENIED";
    case grpc::StatusCode::RESOURCE_EXHAUSTED: return "RESOURCE_EXHAUSTED";
    case grpc::StatusCode::FAILED_PRECONDITION: return "FAILED_PRECONDITION";
    case grpc::StatusCode::ABORTED: return "ABORTED";
    case grpc::StatusCode::OUT_OF_RANGE: return "OUT_OF_RANGE";
    case grpc::StatusCode::UNIMPLEMENTED: return "UNIMPLEMENTED";
    case grpc::StatusCode::INTERNAL: return "INTERNAL";
    case grpc::StatusCode::UNAVAILABLE: return "UNAVAILABLE";
    case grpc::StatusCode::DATA_LOSS: return "DATA_LOSS";
    case grpc::StatusCode::UNAUTHENTICATED: return "UNAUTHENTICATED";
    default: return "UNKNOWN";
  }
}

Metrics::Metrics()
    : registry_(std::make_shared<prometheus::Registry>()),
      sessions_family_(BuildGauge().Name("cinevol_sessions").Help("Sessions held, by state").Register(*registry_)),
      starting_(sessions_family_.Add({{"state", "starting"}})),
      rendering_(sessions_family_.Add({{"state", "rendering"}})),
      idle_(sessions_family_.Add({{"state", "idle"}})),
      paused_(sessions_family_.Add({{"state", "paused"}})),
      detached_(sessions_family_.Add({{"state", "detached"}})),
      frames_sent_(BuildCounter()
                       .Name("cinevol_frames_sent_total")
                       .Help("Frames written to viewers' streams")
                       .Register(*registry_)
                       .Add({})),
      frames_dropped_(BuildCounter()
                          .Name("cinevol_frames_dropped_total")
                          .Help("Frames rendered and encoded but never sent (a newer frame replaced them)")
                          .Register(*registry_)
                          .Add({})),
      frames_rendered_(BuildCounter()
                           .Name("cinevol_frames_rendered_total")
                           .Help("Frames sessions rendered")
                           .Register(*registry_)
                           .Add({})),
      events_received_(BuildCounter()
                           .Name("cinevol_events_received_total")
                           .Help("Session events received from viewers")
                           .Register(*registry_)
                           .Add({})),
      events_coalesced_(BuildCounter()
                            .Name("cinevol_events_coalesced_total")
                            .Help("Events over --max-events-per-second, merged into the next frame's")
                            .Register(*registry_)
                            .Add({})),
      stage_family_(BuildHistogram()
                        .Name("cinevol_stage_seconds")
                        .Help("Time a streamed frame spent in each stage")
                        .Register(*registry_)),
      render_(stage_family_.Add({{"stage", "render"}}, StageBuckets())),
      denoise_(stage_family_.Add({{"stage", "denoise"}}, StageBuckets())),
      tonemap_(stage_family_.Add({{"stage", "tonemap"}}, StageBuckets())),
      encode_(stage_family_.Add({{"stage", "encode"}}, StageBuckets())),
      send_(stage_family_.Add({{"stage", "send"}}, StageBuckets())),
      sent_bytes_(BuildCounter()
                      .Name("cinevol_sent_bytes_total")
                      .Help("JPEG bytes of the frames sent")
                      .Register(*registry_)
                      .Add({})),
      device_memory_family_(BuildGauge()
                                .Name("cinevol_device_memory_used_bytes")
                                .Help("GPU memory in use (total - free), by device")
                                .Register(*registry_)),
      volume_memory_(BuildGauge()
                         .Name("cinevol_volume_memory_bytes")
                         .Help("Host memory of the volumes held")
                         .Register(*registry_)
                         .Add({})),
      uploads_family_(BuildCounter()
                          .Name("cinevol_uploads_total")
                          .Help("Volume uploads finished, by result")
                          .Register(*registry_)),
      uploads_ok_(uploads_family_.Add({{"result", "ok"}})),
      uploads_error_(uploads_family_.Add({{"result", "error"}})),
      limit_refusals_family_(BuildCounter()
                                 .Name("cinevol_limit_refusals_total")
                                 .Help("Requests refused for passing one of the server's limits, by flag")
                                 .Register(*registry_)),
      reader_outcomes_family_(BuildCounter()
                                  .Name("cinevol_reader_outcomes_total")
                                  .Help("Files read in the reader cage, by how the reader ended (ok, refused, "
                                        "crashed, sandbox, memory, cpu, timeout, cancelled, protocol)")
                                  .Register(*registry_)),
      errors_family_(BuildCounter()
                         .Name("cinevol_errors_total")
                         .Help("Error statuses returned to callers, by gRPC code")
                         .Register(*registry_)),
      connections_shed_(BuildCounter()
                            .Name("cinevol_connections_shed_total")
                            .Help("Connections closed on arrival (--max-connections, or out of descriptors)")
                            .Register(*registry_)
                            .Add({})) {}

void Metrics::FrameSent(std::uint64_t bytes, double send_seconds) {
  frames_sent_.Increment();
  sent_bytes_.Increment(double(bytes));
  send_.Observe(send_seconds);
}

void Metrics::ObserveStage(Stage stage, double seconds) {
  switch (stage) {
    case Stage::kRender: render_.Observe(seconds); break;
    case Stage::kDenoise: denoise_.Observe(seconds); break;
    case Stage::kTonemap: tonemap_.Observe(seconds); break;
    case Stage::kEncode: encode_.Observe(seconds); break;
    case Stage::kSend: send_.Observe(seconds); break;
  }
}

// The flags are the server's own limit names: a bounded set.
void Metrics::LimitRefused(const std::string& flag) { limit_refusals_family_.Add({{"limit", flag}}).Increment(); }

void Metrics::ReaderEnded(std::string_view outcome) {
  reader_outcomes_family_.Add({{"outcome", std::string(outcome)}}).Increment();
}

void Metrics::Error(grpc::StatusCode code) {
  if (code == grpc::StatusCode::OK) return;
  errors_family_.Add({{"code", StatusCodeLabel(code)}}).Increment();
}

void Metrics::SetSessions(const SessionStates& s) {
  starting_.Set(s.starting);
  rendering_.Set(s.rendering);
  idle_.Set(s.idle);
  paused_.Set(s.paused);
  detached_.Set(s.detached);
}

void Metrics::SetDeviceMemoryUsed(int gpu, std::uint64_t bytes) {
  device_memory_family_.Add({{"device", fmt::format("cuda:{}", gpu)}}).Set(double(bytes));
}

void Metrics::SetConnectionsShed(std::uint64_t total) {
  std::lock_guard lock(mu_);
  if (total > shed_seen_) connections_shed_.Increment(double(total - shed_seen_));
  shed_seen_ = std::max(shed_seen_, total);
}

Metrics& ServerMetrics() {
  static Metrics* metrics = new Metrics();  // never destroyed: detached threads may still count at exit
  return *metrics;
}

}  // namespace cinevol::service

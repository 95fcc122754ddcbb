// Connection limits: descriptors, channel arguments, resource quota.
#include "service/connection_limits.h"

#include <grpcpp/resource_quota.h>
#include <spdlog/spdlog.h>
#include <sys/resource.h>

#include <algorithm>

namespace cinevol::service {
namespace {

// Descriptors kept back from connections: volumes, uploads, DICOM files,
// pipes and gRPC's own.
constexpr int kReservedDescriptors = 256;

}  // namespace

int PrepareDescriptors(const ConnectionLimits& limits) {
  rlimit limit{};
  getrlimit(RLIMIT_NOFILE, &limit);
  if (limit.rlim_cur < limit.rlim_max) {
    limit.rlim_cur = limit.rlim_max;
    setrlimit(RLIMIT_NOFILE, &limit);
    getrlimit(RLIMIT_NOFILE, &limit);
  }
  const int available = int(std::min<rlim_t>(limit.rlim_cur, 1 << 24));
  const int cap = std::min(limits.max_connections + kReservedDescriptors, available - kReservedDescriptors);
  ConfigureAcceptGuard(std::max(cap, 32));
  if (cap < limits.max_connections) {
    spdlog::warn("descriptor limit {}: connections capped at about {} (--max-connections {})", available,
                 std::max(cap - kReservedDescriptors, 0), limits.max_connections);
  }
  return available;
}

void ApplyConnectionLimits(const ConnectionLimits& limits, grpc::ServerBuilder& builder) {
  builder.AddChannelArgument(GRPC_ARG_MAX_CONCURRENT_STREAMS, limits.max_streams_per_connection);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, limits.keepalive_seconds * 1000);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, 10'000);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  // Clients may ping as often as every 10 s without being cut off.
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS, 10'000);
  builder.AddChannelArgument(GRPC_ARG_SERVER_HANDSHAKE_TIMEOUT_MS, limits.handshake_seconds * 1000);
  builder.AddChannelArgument(GRPC_ARG_MAX_CONNECTION_IDLE_MS, limits.idle_connection_seconds * 1000);
  grpc::ResourceQuota quota("cinevol-transport");
  quota.Resize(std::size_t(limits.transport_memory_mb) << 20);
  builder.SetResourceQuota(quota);
}

}  // namespace cinevol::service

// What one client can hold of the transport: connections (file descriptors),
// streams per connection, transport memory, and how long a silent or dead
// peer keeps its connection. Applied once, when the server starts.
#pragma once

#include <grpcpp/server_builder.h>

#include <cstdint>

namespace cinevol::service {

struct ConnectionLimits {
  int max_connections = 4096;            // about this many sockets at once; past it new ones are closed at once
  int max_streams_per_connection = 128;  // concurrent calls on one connection
  int keepalive_seconds = 30;            // ping a quiet connection this often; no answer in 10 s ends it
  int handshake_seconds = 10;            // a connection that has not spoken HTTP/2 (and TLS) by then is closed
  int idle_connection_seconds = 600;     // a connection without calls this long is closed
  std::uint64_t transport_memory_mb = 1024;  // gRPC's ResourceQuota
};

// Raises the soft descriptor limit to the hard one (a busy server needs
// them) and sets up the accept guard for `limits` (accept_guard.cpp).
// Returns the descriptor limit now in force.
int PrepareDescriptors(const ConnectionLimits& limits);

// Channel arguments and the resource quota of `limits`.
void ApplyConnectionLimits(const ConnectionLimits& limits, grpc::ServerBuilder& builder);

// The accept guard: connections whose descriptor number reaches
// `max_descriptor` are closed as they arrive, and running out of descriptors
// sheds the waiting connection instead of stopping the listener. 0: off.
void ConfigureAcceptGuard(int max_descriptor);
// Connections the guard closed since start.
std::uint64_t ShedConnections();

}  // namespace cinevol::service

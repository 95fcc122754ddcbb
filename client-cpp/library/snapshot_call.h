// One still over StreamSnapshot: the server's updates arrive on gRPC's
// threads, the caller's thread waits, reports progress and decides when to
// give up (a timeout, the server's silence, a cancel).
#pragma once

#include <chrono>
#include <memory>
#include <string>

#include "client.h"

namespace cinevol {

// Runs the still on `stub` and returns it; throws RpcError (UNIMPLEMENTED
// from a server without StreamSnapshot). `context` carries the token and no
// deadline.
v1::SnapshotResponse StreamStill(v1::SessionService::Stub& stub, std::unique_ptr<grpc::ClientContext> context,
                                 const v1::SnapshotRequest& request, const SnapshotOptions& options,
                                 std::chrono::milliseconds silence);

}  // namespace cinevol

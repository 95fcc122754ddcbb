// Who is calling: every RPC passes Authenticate before it does anything, and
// each session records the principal that created it. Today every caller is
// "anonymous"; bearer tokens and mutual TLS (the hardening issue) plug in
// here and nowhere else. Health checking and reflection stay open (probes).
#pragma once

#include <grpcpp/server_context.h>

#include <string>

namespace cinevol::service {

struct Principal {
  std::string name;
};

// The caller's principal, or throws RpcError(UNAUTHENTICATED).
Principal Authenticate(const grpc::CallbackServerContext& context);

// Throws RpcError(PERMISSION_DENIED) unless `caller` owns what `owner` owns.
void RequireOwner(const Principal& caller, const std::string& owner, const std::string& what);

}  // namespace cinevol::service

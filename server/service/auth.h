// Who is calling: every RPC passes Authenticator::Authenticate before it does
// anything, and each session records the principal that created it. Without
// a token file every caller is "anonymous"; with one (--auth-tokens), a call
// must carry `authorization: Bearer <token>` naming a listed token. Mutual
// TLS (the hardening issue) plugs in here too. Health checking and
// reflection stay open (probes).
#pragma once

#include <grpcpp/server_context.h>

#include <filesystem>
#include <map>
#include <string>

namespace cinevol::service {

struct Principal {
  std::string name;
};

class Authenticator {
 public:
  // Open: everyone is "anonymous".
  Authenticator() = default;
  // Reads "TOKEN PRINCIPAL" lines (blank lines and # comments skipped);
  // throws InputError naming the file and line.
  explicit Authenticator(const std::filesystem::path& token_file);

  // The caller's principal, or throws RpcError(UNAUTHENTICATED).
  Principal Authenticate(const grpc::CallbackServerContext& context) const;

 private:
  std::map<std::string, std::string, std::less<>> principals_;  // token -> principal
};

// Throws RpcError(PERMISSION_DENIED) unless `caller` is `owner`.
void RequireOwner(const Principal& caller, const std::string& owner, const std::string& what);

}  // namespace cinevol::service

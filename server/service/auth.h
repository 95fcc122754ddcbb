// Who is calling: every RPC passes Authenticator::Authenticate before it does
// anything, and each session records the principal that created it.
//
//   no token file, no client certificates   every caller is "anonymous"
//   --auth-tokens FILE                       `authorization: Bearer <token>`
//                                            must name a listed token; its
//                                            line names the principal
//   mutual TLS (--tls-client-ca)             the principal is the verified
//                                            client certificate's subject CN
//   mutual TLS and --auth-tokens             both: the certificate to connect,
//                                            the token names the principal
//
// The token file holds lines `TOKEN PRINCIPAL` or `TOKEN PRINCIPAL operator`
// (blank lines and # comments skipped); `operator` marks an operator
// principal. Reload() (cinevol-server does it on SIGHUP) re-reads it; calls
// see the old or the new set, never a mix. Tokens are compared in constant
// time and never logged. A call with more than one `authorization` header is
// refused (UNAUTHENTICATED), whatever the configuration. Reflection passes
// here too; only gRPC health checking stays open (probes carry no token).
#pragma once

#include <grpcpp/server_context.h>

#include <filesystem>
#include <memory>
#include <string>

#include "runtime/principal.h"

namespace cinevol::service {


class Authenticator {
 public:
  // Open: everyone is "anonymous" unless a verified client certificate names them.
  Authenticator() = default;
  // Reads the token file; throws InputError naming the file and line.
  explicit Authenticator(const std::filesystem::path& token_file);

  // The caller's principal, or throws RpcError(UNAUTHENTICATED).
  Principal Authenticate(const grpc::CallbackServerContext& context) const;
  // The same, from a call's auth context and `authorization` header value
  // (null when absent): what Authenticate does, for tests and other callers.
  Principal Authenticate(const grpc::AuthContext* auth_context, const std::string* authorization) const;

  // Re-reads the token file. On error (InputError naming file and line) the
  // tokens in use stay. Without a token file it does nothing.
  void Reload();
  // For a PACS that takes the caller's own token (--pacs-auth forward): each
  // principal carries its call's bearer token, and without a token file a
  // token (not a certificate) names the caller, "bearer:" and 16 hex digits
  // of its SHA-256, so one user's PACS data never reaches another's calls.
  void ForwardBearerTokens() { forwards_tokens_ = true; }
  bool has_tokens() const { return tokens_ != nullptr; }
  std::size_t token_count() const;

  struct TokenFile;  // the file and its current tokens, shared by copies

 private:
  std::shared_ptr<TokenFile> tokens_;  // null: no token file
  bool forwards_tokens_ = false;
};

// Reloads the token file of every Authenticator alive in this process (the
// server's lives inside its ServiceCore); main.cpp calls it on SIGHUP. Logs
// the outcome (never a token) and returns false when some file could not be
// loaded (its old tokens stay).
bool ReloadAllTokenFiles();

}  // namespace cinevol::service

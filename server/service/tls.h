// Transport security of cinevol-server: TLS (--tls-cert/--tls-key), mutual
// TLS (--tls-client-ca: clients must show a certificate that CA signed), and
// the listen policy that keeps an unauthenticated server on loopback.
#pragma once

#include <grpcpp/security/server_credentials.h>

#include <filesystem>
#include <memory>
#include <string>

namespace cinevol::service {

struct TlsOptions {
  std::filesystem::path cert;       // PEM server certificate (chain), --tls-cert
  std::filesystem::path key;        // PEM private key of `cert`, --tls-key
  std::filesystem::path client_ca;  // PEM CA certificates clients must chain to, --tls-client-ca

  bool enabled() const { return !cert.empty() || !key.empty() || !client_ca.empty(); }
  bool mutual() const { return !client_ca.empty(); }
};

// Insecure credentials when `tls` is not enabled; otherwise reads and checks
// the PEM files (certificate and key parse and belong together, the client
// CA holds certificates) and returns SslServerCredentials, requiring and
// verifying client certificates when client_ca is set. Throws InputError
// naming the flag and file for a missing, unreadable or bad file.
std::shared_ptr<grpc::ServerCredentials> MakeServerCredentials(const TlsOptions& tls);

// True when the HOST of a HOST:PORT listen address is loopback only:
// 127.0.0.0/8, ::1 ([::1]), localhost, or a unix: socket.
bool IsLoopbackListen(const std::string& listen);

// Refuses (InputError naming --auth-tokens, --tls-cert/--tls-key/
// --tls-client-ca and --insecure-no-auth) to listen beyond loopback without
// bearer tokens or mutual TLS, unless insecure_no_auth. Pure: logs nothing.
void CheckListenPolicy(const std::string& listen, bool has_tokens, bool has_mutual_tls, bool insecure_no_auth);

}  // namespace cinevol::service

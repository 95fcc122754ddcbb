// The options every networked subcommand takes: where the server is, the
// token to show it and the TLS files to reach it with.
#pragma once

#include <CLI/CLI.hpp>

#include <stdexcept>
#include <string>

#include "client.h"
#include "core/error.h"

namespace cinevol::cli {

struct ConnectionOptions {
  std::string server = "127.0.0.1:50051";
  std::string token;
  double connect_seconds = 5;
  double call_seconds = 60;  // each unary call's deadline (--timeout where a command offers it)
  std::string tls_ca, tls_cert, tls_key;  // PEM files; tls_ca set: TLS
};

inline void AddConnectionOptions(CLI::App* command, ConnectionOptions& o) {
  command
      ->add_option("--server", o.server,
                   "Server address HOST:PORT, or a deployment's servers separated by commas (sessions go where "
                   "there is most room and move when theirs dies)")
      ->capture_default_str();
  command->add_option("--token", o.token, "Bearer token, when the server asks for one");
  command->add_option("--connect-timeout", o.connect_seconds, "Seconds to wait for the server")
      ->check(CLI::Range(0.1, 600.0))
      ->capture_default_str();
  command->add_option("--tls-ca", o.tls_ca,
                      "PEM CA certificate(s) the server's certificate must chain to: connect over TLS");
  auto* cert = command->add_option("--tls-cert", o.tls_cert,
                                   "PEM client certificate, for a server that requires one (mutual TLS)");
  auto* key = command->add_option("--tls-key", o.tls_key, "PEM private key of --tls-cert");
  cert->needs(key);
  key->needs(cert);
}

// --timeout S for commands whose calls may take long (a large load or
// upload): each call's deadline, which is 60 s elsewhere.
inline void AddCallTimeoutOption(CLI::App* command, ConnectionOptions& o) {
  command
      ->add_option("--timeout", o.call_seconds, "Seconds the server may take to answer (a large volume takes longer)")
      ->check(CLI::Range(1.0, 7.0 * 86400))
      ->capture_default_str();
}

inline ClientOptions ToClientOptions(const ConnectionOptions& o) {
  ClientOptions options;
  options.address = o.server;
  options.token = o.token;
  options.connect_timeout = std::chrono::milliseconds(static_cast<long>(o.connect_seconds * 1000));
  options.call_timeout = std::chrono::milliseconds(static_cast<long>(o.call_seconds * 1000));
  options.tls_ca = o.tls_ca;
  options.tls_cert = o.tls_cert;
  options.tls_key = o.tls_key;
  return options;
}

// Throws RpcError(UNAVAILABLE) when the server cannot be reached in time.
inline Client Connect(const ConnectionOptions& o) {
  try {
    return Client(ToClientOptions(o));
  } catch (const std::invalid_argument& e) {  // an unreadable TLS file
    throw InputError(e.what());
  }
}

}  // namespace cinevol::cli

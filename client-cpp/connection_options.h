// The options every networked subcommand takes: where the server is and the
// token to show it.
#pragma once

#include <CLI/CLI.hpp>

#include <string>

#include "client.h"

namespace cinevol::cli {

struct ConnectionOptions {
  std::string server = "127.0.0.1:50051";
  std::string token;
  double connect_seconds = 5;
};

inline void AddConnectionOptions(CLI::App* command, ConnectionOptions& o) {
  command->add_option("--server", o.server, "Server address HOST:PORT")->capture_default_str();
  command->add_option("--token", o.token, "Bearer token, when the server asks for one");
  command->add_option("--connect-timeout", o.connect_seconds, "Seconds to wait for the server")
      ->check(CLI::Range(0.1, 600.0))
      ->capture_default_str();
}

// Throws RpcError(UNAVAILABLE) when the server cannot be reached in time.
inline Client Connect(const ConnectionOptions& o) {
  ClientOptions options;
  options.address = o.server;
  options.token = o.token;
  options.connect_timeout = std::chrono::milliseconds(static_cast<long>(o.connect_seconds * 1000));
  return Client(options);
}

}  // namespace cinevol::cli

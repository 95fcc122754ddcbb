// How a cinevol::Client reaches its servers, and the error its calls throw.
#pragma once

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <filesystem>
#include <stdexcept>
#include <string>

namespace cinevol {

struct ClientOptions {
  // The server, HOST:PORT (or any gRPC target), or several separated by
  // commas: the servers of one deployment (e.g. the pods of a StatefulSet).
  // Volume and status calls go to the first that answers; a new session
  // goes to the one with the most room; a session whose server goes away is
  // re-created on another (StreamOptions::failover).
  std::string address = "127.0.0.1:50051";
  std::string token;  // sent as "authorization: Bearer <token>" when set
  std::chrono::milliseconds connect_timeout{5000};
  std::chrono::milliseconds call_timeout{60000};  // every unary call; loads included, snapshots not
  // A snapshot has no deadline of its own (SnapshotOptions::timeout sets
  // one): it is given up when the server reports no progress for this long.
  // The server reports about once a second; a step of a still on a slow CPU
  // (4K, a dense CT) takes at most some tens of seconds.
  std::chrono::milliseconds snapshot_silence{120000};
  // While a call is open (a stream that gets no frames included), ping the
  // server this often; a ping unanswered for keepalive_timeout ends the
  // connection. That is how a stream notices a server whose machine went
  // away without closing it (a node lost, a network cut), instead of waiting
  // minutes for TCP. The server accepts pings every 10 s at most.
  std::chrono::milliseconds keepalive{20000};
  std::chrono::milliseconds keepalive_timeout{10000};
  // TLS (PEM files, read when the Client is constructed). With tls_ca the
  // channel is TLS and the server's certificate must chain to that CA;
  // tls_cert and tls_key (together) add a client certificate for servers
  // that require one (mutual TLS). A client key or certificate without
  // tls_ca trusts the system's root certificates. None set: plaintext.
  std::filesystem::path tls_ca;
  std::filesystem::path tls_cert;
  std::filesystem::path tls_key;
};

// A call the server refused or could not answer: its status code and message.
class RpcError : public std::runtime_error {
 public:
  explicit RpcError(const grpc::Status& status);
  grpc::StatusCode code() const { return code_; }

 private:
  grpc::StatusCode code_;
};

// "INVALID_ARGUMENT" and the like.
std::string StatusCodeName(grpc::StatusCode code);

// Throws RpcError unless `status` is OK.
void Check(const grpc::Status& status);

}  // namespace cinevol

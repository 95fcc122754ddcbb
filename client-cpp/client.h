// cinevol::Client: the C++ client of cinevol-server. Connects, manages
// volumes and sessions with unary calls (each bounded by a deadline), and
// attaches to a session's stream: events go out with increasing sequence
// numbers, frames and notices come back through Next() or a callback, and a
// dropped connection is resumed while the server still holds the session.
//
//   cinevol::Client client({.address = "127.0.0.1:50051"});
//   auto created = client.CreateSession(request);
//   auto stream = client.Attach(created.session_id());
//   stream->Send(camera_event);
//   while (auto message = stream->Next(std::chrono::seconds(1))) { ... }
#pragma once

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "cinevol/v1/service.grpc.pb.h"

namespace cinevol {

struct ClientOptions {
  std::string address = "127.0.0.1:50051";
  std::string token;  // sent as "authorization: Bearer <token>" when set
  std::chrono::milliseconds connect_timeout{5000};
  std::chrono::milliseconds call_timeout{60000};  // every unary call; snapshots and loads included
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

// A frame's pixels: 8-bit sRGB, rows top to bottom.
struct RgbImage {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  // width * height * 3
};

// A frame's encoded image: its JPEG, or its PNG (a final frame, where the
// stream's final_format asks for one).
const std::string& EncodedImage(const v1::Frame& frame);
// Decodes a frame's image; throws std::runtime_error when it is not one.
RgbImage DecodeFrame(const v1::Frame& frame);

struct StreamOptions {
  // Called on the stream's reader thread with every message from the server;
  // when set, Next() returns nothing. It must not block for long.
  std::function<void(const v1::ServerMessage&)> on_message;
  // After a dropped connection (UNAVAILABLE), attach again while the server
  // still holds the session; sequence numbers start again at 1.
  bool resume = true;
  std::chrono::milliseconds resume_timeout{10000};  // per drop, reconnecting included
};

// One attached session stream. A thread reads the server's messages into a
// queue (or hands them to on_message); Next takes them in order.
class SessionStream {
 public:
  SessionStream(std::shared_ptr<grpc::Channel> channel, std::string session_id, std::string token,
                StreamOptions options);
  ~SessionStream();  // cancels the call if it is still open
  SessionStream(const SessionStream&) = delete;
  SessionStream& operator=(const SessionStream&) = delete;

  // Sends `event` with the next sequence number (1, 2, ...) and returns it,
  // or 0 when it could not be sent (the stream has ended or is reconnecting).
  std::uint64_t Send(v1::SessionEvent event);
  // The next message, waiting up to `timeout`; nullopt on timeout or once
  // the stream has ended and every message was taken (then see status()).
  std::optional<v1::ServerMessage> Next(std::chrono::milliseconds timeout);
  // When event `seq` of the current connection went out, for latency.
  std::chrono::steady_clock::time_point SentAt(std::uint64_t seq) const;
  // Closes the sending side and waits up to `timeout` for the server's status.
  grpc::Status Finish(std::chrono::milliseconds timeout);
  // Drops the call, as a client that goes away does (no resume).
  void Cancel();
  bool ended() const;
  grpc::Status status() const;  // OK until the stream ends
  int resumes() const;          // times the stream reattached after a drop

 private:
  void Open();  // a new call that attaches; call_mu_ held
  void ReadAll();
  bool Resume();  // reattaches after a drop; false when it cannot
  void Deliver(v1::ServerMessage message);

  const std::shared_ptr<grpc::Channel> channel_;
  const std::unique_ptr<v1::SessionService::Stub> stub_;
  const std::string session_id_, token_;
  const StreamOptions options_;

  std::mutex call_mu_;  // the call and its write side
  std::unique_ptr<grpc::ClientContext> context_;
  std::unique_ptr<grpc::ClientReaderWriter<v1::ClientMessage, v1::ServerMessage>> stream_;
  bool writes_closed_ = false;  // by Finish or Cancel: no resume
  bool reconnecting_ = false;
  std::uint64_t next_seq_ = 1;

  mutable std::mutex mu_;  // what the reader delivers
  std::condition_variable arrived_;
  std::deque<v1::ServerMessage> inbox_;
  std::map<std::uint64_t, std::chrono::steady_clock::time_point> sent_at_;
  bool ended_ = false;
  grpc::Status status_;
  int resumes_ = 0;
  std::thread reader_;
};

class Client {
 public:
  // Connects; throws RpcError(UNAVAILABLE) when the server cannot be reached
  // within options.connect_timeout (a TLS handshake that fails included),
  // and std::invalid_argument when a TLS file cannot be read.
  explicit Client(const ClientOptions& options);

  std::vector<v1::VolumeInfo> ListVolumes();
  v1::VolumeInfo LoadVolume(const std::string& path, const std::string& series_uid = {});
  v1::VolumeInfo UploadVolume(const std::filesystem::path& file, std::size_t chunk_bytes = 1 << 20);
  // A segmentation for a loaded volume: a label volume on the server (under
  // its data roots) or a local file, each with an optional label table.
  v1::VolumeInfo LoadLabels(const std::string& volume_id, const std::string& path, const std::string& table_path = {});
  v1::VolumeInfo UploadLabels(const std::string& volume_id, const std::filesystem::path& file,
                              const std::filesystem::path& table = {});
  v1::VolumeInfo DescribeVolume(const std::string& volume_id);
  void UnloadVolume(const std::string& volume_id);

  v1::CreateSessionResponse CreateSession(const v1::CreateSessionRequest& request);
  std::unique_ptr<SessionStream> Attach(const std::string& session_id, StreamOptions options = {});
  v1::SnapshotResponse Snapshot(const v1::SnapshotRequest& request);
  void CloseSession(const std::string& session_id);
  v1::ServerStatus Status();

  const std::shared_ptr<grpc::Channel>& channel() const { return channel_; }

 private:
  std::unique_ptr<grpc::ClientContext> CallContext() const;

  ClientOptions options_;
  std::shared_ptr<grpc::Channel> channel_;
  // Streams `file` after a header of `fields` (its name and size set here).
  v1::VolumeInfo Upload(const std::filesystem::path& file, v1::UploadVolumeChunk::Header fields, std::size_t chunk_bytes);

  std::unique_ptr<v1::VolumeService::Stub> volumes_;
  std::unique_ptr<v1::SessionService::Stub> sessions_;
  std::unique_ptr<v1::ServerService::Stub> server_;
};

}  // namespace cinevol

// Watching a shared session (docs/sharing.md): WatchSession by a grant's
// secret, read on a thread of its own. Client::Watch opens one; the owner's
// calls (Share, ListShares, RevokeShare, HandOver) are Client's.
#pragma once

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "cinevol/v1/service.grpc.pb.h"

namespace cinevol {

class SessionWatch {
 public:
  // Watches by `grant` on `channel`; `token` (may be empty) signs in a
  // principal's grant (a link needs none).
  SessionWatch(std::shared_ptr<grpc::Channel> channel, std::string grant, const std::string& token);
  ~SessionWatch();  // cancels the call if it is still open
  SessionWatch(const SessionWatch&) = delete;
  SessionWatch& operator=(const SessionWatch&) = delete;

  // The next message (frame, state, notice), waiting up to `timeout`;
  // nullopt on timeout or once the stream ended and every message was taken.
  std::optional<v1::ServerMessage> Next(std::chrono::milliseconds timeout);
  // Events as the grant's holder (a presenter's; a viewer's pointer). The
  // session numbers them; the state it answers says how far it got.
  v1::SessionState Send(const std::vector<v1::SessionEvent>& events);
  // Stops reading, as a viewer that leaves.
  void Cancel();
  bool ended() const;
  grpc::Status status() const;                    // OK until the stream ends
  std::optional<v1::SessionState> state() const;  // the newest the server sent

 private:
  void ReadAll();
  std::unique_ptr<grpc::ClientContext> Context() const;

  const std::string grant_, token_;
  std::unique_ptr<v1::SessionService::Stub> stub_;
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReader<v1::ServerMessage>> reader_;

  mutable std::mutex mu_;
  std::condition_variable arrived_;
  std::deque<v1::ServerMessage> inbox_;
  std::optional<v1::SessionState> state_;
  bool ended_ = false;
  grpc::Status status_;
  std::thread thread_;
};

}  // namespace cinevol

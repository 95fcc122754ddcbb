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
#include <vector>

#include "cinevol/v1/service.grpc.pb.h"

namespace cinevol {

class SessionWatch {
 public:
  // Watches by `grant` on the first of `channels`; `token` (may be empty)
  // signs in a principal's grant (a link needs none). When the server goes
  // (UNAVAILABLE) or no longer holds the session (NOT_FOUND), the watch looks
  // for it on the other channels for up to `follow` (a failover moved it there
  // with its grants: docs/sharing.md).
  SessionWatch(std::vector<std::shared_ptr<grpc::Channel>> channels, std::string grant, const std::string& token,
               std::chrono::seconds follow = std::chrono::seconds(30));
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
  int follows() const;                            // times the watch found its session on another server

 private:
  void ReadAll();
  // Reads a call on channels_[index] to its end; whether anything arrived.
  bool ReadFrom(std::size_t index, grpc::Status& status);
  std::unique_ptr<grpc::ClientContext> Context() const;

  const std::vector<std::shared_ptr<grpc::Channel>> channels_;
  const std::string grant_, token_;
  const std::chrono::seconds follow_;

  mutable std::mutex mu_;
  std::condition_variable arrived_;
  std::deque<v1::ServerMessage> inbox_;
  std::optional<v1::SessionState> state_;
  bool ended_ = false, cancelled_ = false;
  grpc::Status status_;
  std::size_t current_ = 0;  // the channel watched now (Send goes there)
  int follows_ = 0;
  bool following_ = false;               // the server watched went or lost the session: looking for where it moved
  grpc::ClientContext* call_ = nullptr;  // the call being read, for Cancel
  std::thread thread_;
};

}  // namespace cinevol

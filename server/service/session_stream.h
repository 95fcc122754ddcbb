// The session calls' reactors: StreamSession (attach and events in; frames,
// notices and states out) and WatchSession, its server half for clients that
// cannot stream both ways. Both write through FrameWriter: one write in
// flight; a frame that finishes meanwhile waits in a one-frame slot, where a
// newer frame replaces it (newest wins); notices and states queue ahead of
// frames. Reactions never block: they take short locks and hand work to the
// session.
#pragma once

#include <grpcpp/alarm.h>
#include <grpcpp/grpcpp.h>

#include <deque>
#include <memory>
#include <mutex>
#include <optional>

#include "cinevol/v1/service.grpc.pb.h"
#include "runtime/session.h"
#include "runtime/token_bucket.h"
#include "service/auth.h"
#include "service/call_watch.h"

namespace cinevol::service {

class ServiceCore;

using BidiSessionReactor = grpc::ServerBidiReactor<v1::ClientMessage, v1::ServerMessage>;
using WriteSessionReactor = grpc::ServerWriteReactor<v1::ServerMessage>;

// The write side of a call attached to a session, over either reactor above
// (session_stream.cpp instantiates both). The derived reactor attaches
// (AttachTo) and, in OnDone, detaches (DetachFromSession) before deleting itself.
template <class Reactor>
class FrameWriter : public Reactor, public FrameStream {
 public:
  // FrameStream, called by the session (under its lock).
  void OfferFrame(v1::Frame frame, Clock::time_point origin) override;
  void SendNotice(v1::Notice::Level level, std::string message) override;
  void SendState(v1::SessionState state) override;
  bool SlotFull() const override;
  void End(grpc::Status status) override;
  void EndSession(grpc::Status status) override;
  std::uint64_t frames_sent() const override;
  std::uint64_t frames_dropped() const override;

  // Reactions.
  void OnWriteDone(bool ok) override;
  void OnCancel() override;

 protected:
  explicit FrameWriter(grpc::CallbackServerContext* context) : context_(context) {}

  // Makes this call `session`'s stream; the stream attached before ends with
  // ABORTED. With a `grant_id`, a watcher's stream instead (Session::
  // AttachWatcher): nobody's stream ends. Throws (NOT_FOUND) when the
  // session has ended.
  void AttachTo(std::shared_ptr<Session> session, const std::string& grant_id = {}, const std::string& holder = {});
  void DetachFromSession();
  std::shared_ptr<Session> session() const;  // null until AttachTo
  void FinishLocked(const grpc::Status& status);

  mutable std::mutex mu_;
  bool finished_ = false;  // Finish was called

 private:
  // A notice or state: now, or after the write in flight (before any frame).
  void SendMessage(v1::ServerMessage message);
  void StartWriteLocked(v1::ServerMessage message, bool is_frame);

  grpc::CallbackServerContext* context_;
  std::shared_ptr<Session> session_;
  v1::ServerMessage out_;  // the write in flight
  bool writing_ = false;
  bool writing_frame_ = false;
  Clock::time_point write_started_;  // of the frame in flight (cinevol_stage_seconds{stage="send"})
  struct Parked {
    v1::Frame frame;
    Clock::time_point origin;
  };
  std::optional<Parked> slot_;
  std::deque<v1::ServerMessage> messages_;  // notices and states waiting for the write in flight
  std::optional<grpc::Status> finish_after_write_;
  std::uint64_t sent_ = 0, dropped_ = 0;
};

// StreamSession: the first message attaches, the rest are events.
class SessionStreamReactor final : public FrameWriter<BidiSessionReactor> {
 public:
  SessionStreamReactor(grpc::CallbackServerContext* context, ServiceCore* core);

  void OnReadDone(bool ok) override;
  void OnDone() override;

 private:
  void HandleAttach(const v1::Attach& attach);
  // Reads the next message, at once or, past the stream's read rate, when
  // the pacing alarm rings: past it the client's sends wait in the transport
  // (HTTP/2 flow control) instead of costing the server a read each.
  void ReadNextLocked();
  void OnPaced();

  ServiceCore* core_;
  std::optional<Principal> principal_;  // empty when authentication failed
  CallWatch::Id watch_ = 0;             // until the attach arrives
  v1::ClientMessage in_;                // the read in flight

  // Under mu_.
  TokenBucket reads_;  // kReadPacing x --max-events-per-second
  grpc::Alarm pace_;
  bool pacing_ = false;  // pace_ is set
  bool done_ = false;    // OnDone ran
};

// WatchSession: attaches at once, as StreamSession's attach does; the
// events come by SendEvents.
class WatchSessionReactor final : public FrameWriter<WriteSessionReactor> {
 public:
  WatchSessionReactor(grpc::CallbackServerContext* context, ServiceCore* core, const v1::WatchSessionRequest& request);

  void OnDone() override;
};

}  // namespace cinevol::service

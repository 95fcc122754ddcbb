// The StreamSession call's reactor: reads attach and events from the viewer,
// writes frames and notices to it. One write is in flight at a time; a frame
// that finishes meanwhile waits in a one-frame slot, where a newer frame
// replaces it (newest wins). Notices queue ahead of frames. Reactions never
// block: they take short locks and hand work to the session.
#pragma once

#include <grpcpp/alarm.h>
#include <grpcpp/grpcpp.h>

#include <deque>
#include <memory>
#include <mutex>
#include <optional>

#include "cinevol/v1/service.grpc.pb.h"
#include "service/auth.h"
#include "service/call_watch.h"
#include "runtime/session.h"
#include "runtime/token_bucket.h"

namespace cinevol::service {

class ServiceCore;

// Events are read at most this many times --max-events-per-second; the
// session coalesces those past --max-events-per-second.
inline constexpr int kReadPacing = 4;

class SessionStreamReactor final : public grpc::ServerBidiReactor<v1::ClientMessage, v1::ServerMessage>,
                                   public FrameStream {
 public:
  SessionStreamReactor(grpc::CallbackServerContext* context, ServiceCore* core);

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
  void OnReadDone(bool ok) override;
  void OnWriteDone(bool ok) override;
  void OnCancel() override;
  void OnDone() override;

 private:
  void HandleAttach(const v1::Attach& attach);
  // Reads the next message, at once or, past the stream's read rate, when
  // the pacing alarm rings: past it the client's sends wait in the transport
  // (HTTP/2 flow control) instead of costing the server a read each.
  void ReadNextLocked();
  void OnPaced();
  // A notice or state: now, or after the write in flight (before any frame).
  void SendMessage(v1::ServerMessage message);
  void StartWriteLocked(v1::ServerMessage message, bool is_frame);
  void FinishLocked(const grpc::Status& status);
  std::shared_ptr<Session> session() const;

  grpc::CallbackServerContext* context_;
  ServiceCore* core_;
  std::optional<Principal> principal_;  // empty when authentication failed
  CallWatch::Id watch_ = 0;             // until the attach arrives
  v1::ClientMessage in_;                // the read in flight

  mutable std::mutex mu_;
  std::shared_ptr<Session> session_;     // after attach
  v1::ServerMessage out_;                // the write in flight
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
  bool finished_ = false;
  std::uint64_t sent_ = 0, dropped_ = 0;
  TokenBucket reads_;     // kReadPacing x --max-events-per-second
  grpc::Alarm pace_;
  bool pacing_ = false;   // pace_ is set
  bool done_ = false;     // OnDone ran
};

}  // namespace cinevol::service

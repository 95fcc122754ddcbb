// FrameWriter's slot and queue; SessionStreamReactor's attach, events and
// paced reads; WatchSessionReactor's attach.
#include "service/session_stream.h"

#include <fmt/format.h>

#include <algorithm>

#include "runtime/errors.h"
#include "runtime/metrics.h"
#include "service/service_core.h"

namespace cinevol::service {
template <class Reactor>
std::shared_ptr<Session> FrameWriter<Reactor>::session() const {
  std::lock_guard lock(mu_);
  return session_;
}

template <class Reactor>
void FrameWriter<Reactor>::AttachTo(std::shared_ptr<Session> session, const std::string& grant_id,
                                    const std::string& holder) {
  {
    std::lock_guard lock(mu_);
    session_ = session;
  }
  if (grant_id.empty()) {
    session->Attach(this);
  } else {
    session->AttachWatcher(this, grant_id, holder);
  }
}

template <class Reactor>
void FrameWriter<Reactor>::DetachFromSession() {
  if (std::shared_ptr<Session> session = this->session()) session->Detach(this);
}

template <class Reactor>
void FrameWriter<Reactor>::OfferFrame(v1::Frame frame, Clock::time_point origin) {
  std::lock_guard lock(mu_);
  if (finished_ || finish_after_write_) return;
  if (!writing_) {
    frame.mutable_timings()->set_server_us(MicrosBetween(origin, Clock::now()));
    v1::ServerMessage message;
    *message.mutable_frame() = std::move(frame);
    StartWriteLocked(std::move(message), true);
    return;
  }
  if (slot_) {
    ++dropped_;
    ServerMetrics().FrameDropped();
  }
  slot_ = Parked{std::move(frame), origin};
}

template <class Reactor>
void FrameWriter<Reactor>::SendNotice(v1::Notice::Level level, std::string message) {
  v1::ServerMessage out;
  out.mutable_notice()->set_level(level);
  out.mutable_notice()->set_message(std::move(message));
  SendMessage(std::move(out));
}

template <class Reactor>
void FrameWriter<Reactor>::SendState(v1::SessionState state) {
  v1::ServerMessage out;
  *out.mutable_state() = std::move(state);
  SendMessage(std::move(out));
}

template <class Reactor>
void FrameWriter<Reactor>::SendMessage(v1::ServerMessage message) {
  std::lock_guard lock(mu_);
  if (finished_ || finish_after_write_) return;
  if (writing_) {
    // A state is the whole state: a newer one replaces one still waiting, so
    // a slow reader's queue stays as short as its notices.
    const auto waiting =
        std::find_if(messages_.begin(), messages_.end(), [](const v1::ServerMessage& m) { return m.has_state(); });
    if (message.has_state() && waiting != messages_.end()) {
      *waiting = std::move(message);
    } else {
      messages_.push_back(std::move(message));
    }
    return;
  }
  StartWriteLocked(std::move(message), false);
}

template <class Reactor>
bool FrameWriter<Reactor>::SlotFull() const {
  std::lock_guard lock(mu_);
  return slot_.has_value() || finished_ || finish_after_write_.has_value();
}

template <class Reactor>
void FrameWriter<Reactor>::End(grpc::Status status) {
  std::lock_guard lock(mu_);
  if (finished_ || finish_after_write_) return;
  if (writing_) {
    finish_after_write_ = std::move(status);
  } else {
    FinishLocked(status);
  }
}

template <class Reactor>
void FrameWriter<Reactor>::EndSession(grpc::Status status) {
  {
    std::lock_guard lock(mu_);
    if (finished_ || finish_after_write_) return;
    // The client library's SessionStream reads this trailer (client-cpp/library/client.cpp).
    context_->AddTrailingMetadata("cinevol-session-ended", "1");
  }
  End(std::move(status));
}

template <class Reactor>
std::uint64_t FrameWriter<Reactor>::frames_sent() const {
  std::lock_guard lock(mu_);
  return sent_;
}

template <class Reactor>
std::uint64_t FrameWriter<Reactor>::frames_dropped() const {
  std::lock_guard lock(mu_);
  return dropped_;
}

template <class Reactor>
void FrameWriter<Reactor>::StartWriteLocked(v1::ServerMessage message, bool is_frame) {
  out_ = std::move(message);
  writing_ = true;
  writing_frame_ = is_frame;
  if (is_frame) write_started_ = Clock::now();
  this->StartWrite(&out_);  // gRPC runs OnWriteDone on its own thread, never inside this call
}

template <class Reactor>
void FrameWriter<Reactor>::FinishLocked(const grpc::Status& status) {
  finished_ = true;
  if (slot_) {  // never sent
    ++dropped_;
    ServerMetrics().FrameDropped();
  }
  slot_.reset();
  messages_.clear();
  this->Finish(status);
}

template <class Reactor>
void FrameWriter<Reactor>::OnWriteDone(bool ok) {
  std::shared_ptr<Session> wake;
  {
    std::lock_guard lock(mu_);
    writing_ = false;
    if (ok && writing_frame_) {
      ++sent_;
      ServerMetrics().FrameSent(out_.frame().jpeg().size() + out_.frame().png().size(),  // one of them is set
                                std::chrono::duration<double>(Clock::now() - write_started_).count());
    }
    if (finished_) return;
    if (!ok) {
      FinishLocked(finish_after_write_.value_or(RpcError::Unavailable("the stream to the client broke").status()));
      return;
    }
    if (!messages_.empty()) {  // before an end that waits (a notice says why it ends) and the next frame
      v1::ServerMessage out = std::move(messages_.front());
      messages_.pop_front();
      StartWriteLocked(std::move(out), false);
      return;
    }
    if (finish_after_write_) {
      FinishLocked(*finish_after_write_);
      return;
    }
    if (slot_) {
      Parked parked = std::move(*slot_);
      slot_.reset();
      parked.frame.mutable_timings()->set_server_us(MicrosBetween(parked.origin, Clock::now()));
      v1::ServerMessage out;
      *out.mutable_frame() = std::move(parked.frame);
      StartWriteLocked(std::move(out), true);
    }
    wake = session_;  // the slot has room: the session may render again
  }
  if (wake) wake->OnWritable(this);
}

template <class Reactor>
void FrameWriter<Reactor>::OnCancel() {
  End(RpcError::Cancelled("the client went away").status());
}

template class FrameWriter<BidiSessionReactor>;
template class FrameWriter<WriteSessionReactor>;

SessionStreamReactor::SessionStreamReactor(grpc::CallbackServerContext* context, ServiceCore* core)
    : FrameWriter(context),
      core_(core),
      reads_(kReadPacing * core->options().limits.max_events_per_second, Clock::now()) {
  const grpc::Status status = Guarded([&] { principal_ = core_->Authenticate(*context); });
  if (!status.ok()) {
    std::lock_guard lock(mu_);
    FinishLocked(status);
    return;
  }
  // A stream that never attaches is cancelled (--first-message-seconds).
  watch_ = core_->calls().Watch(context, Seconds(core_->options().first_message_seconds));
  StartRead(&in_);
}

void SessionStreamReactor::OnReadDone(bool ok) {
  if (!ok) {  // the client closed its side, or the call is gone
    End(grpc::Status::OK);
    return;
  }
  const Clock::time_point arrival = Clock::now();
  std::shared_ptr<Session> session = this->session();
  if (!session) {
    core_->calls().Forget(watch_);
    if (!in_.has_attach()) {
      End(RpcError::InvalidArgument("attach: the first message must attach to a session").status());
      return;
    }
    const grpc::Status status = Guarded([&] { HandleAttach(in_.attach()); });
    if (!status.ok()) {
      End(status);
      return;
    }
  } else if (in_.has_attach()) {
    End(RpcError::InvalidArgument("attach: this stream is already attached").status());
    return;
  } else {
    const grpc::Status status = Guarded([&] { session->OnEvent(in_.event(), arrival); });
    // A bad event ends the session, with the message naming the field: the
    // stream's client sent it in the stream it watches, and a stream cannot
    // answer one message alone. (SendEvents answers its batch and leaves the
    // session as it was: Session::OnEvents.)
    if (!status.ok()) {
      session->End(status);
      return;
    }
  }
  std::lock_guard lock(mu_);
  ReadNextLocked();
}

void SessionStreamReactor::ReadNextLocked() {
  if (finished_) return;
  const Clock::time_point now = Clock::now();
  const Clock::duration wait = reads_.Wait(now);
  if (wait == Clock::duration::zero()) {
    reads_.Take(now);
    StartRead(&in_);
    return;
  }
  pacing_ = true;
  pace_.Set(std::chrono::system_clock::now() + wait, [this](bool) { OnPaced(); });
}

void SessionStreamReactor::OnPaced() {
  {
    std::lock_guard lock(mu_);
    pacing_ = false;
    if (!done_) {
      ReadNextLocked();
      return;
    }
  }
  delete this;  // OnDone came while the alarm was set and left the deletion to it
}

void SessionStreamReactor::HandleAttach(const v1::Attach& attach) {
  AttachTo(core_->FindSession(attach.session_id(), *principal_));
}

void SessionStreamReactor::OnDone() {
  core_->calls().Forget(watch_);
  DetachFromSession();
  {
    std::lock_guard lock(mu_);
    done_ = true;
    if (pacing_) {  // the pacing alarm's callback deletes the reactor
      pace_.Cancel();
      return;
    }
  }
  delete this;
}

WatchSessionReactor::WatchSessionReactor(grpc::CallbackServerContext* context, ServiceCore* core,
                                         const v1::WatchSessionRequest& request)
    : FrameWriter(context) {
  // Writes may start here, before gRPC holds the reactor: it keeps them until then.
  const grpc::Status status = Guarded([&] {
    if (request.grant().empty()) {
      AttachTo(core->FindSession(request.session_id(), core->Authenticate(*context)));
      return;
    }
    const GrantAccess access = core->sharing().Access(*context, request.session_id(), request.grant());
    AttachTo(access.session, access.grant.id, access.grant.holder());
  });
  if (!status.ok()) End(status);
}

void WatchSessionReactor::OnDone() {
  DetachFromSession();
  delete this;
}

}  // namespace cinevol::service

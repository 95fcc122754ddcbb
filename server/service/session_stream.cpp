// SessionStreamReactor: attach, events in; frames and notices out.
#include "service/session_stream.h"

#include <fmt/format.h>

#include "runtime/errors.h"
#include "runtime/metrics.h"
#include "service/service_core.h"

namespace cinevol::service {

SessionStreamReactor::SessionStreamReactor(grpc::CallbackServerContext* context, ServiceCore* core)
    : context_(context), core_(core), reads_(kReadPacing * core->options().limits.max_events_per_second, Clock::now()) {
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

std::shared_ptr<Session> SessionStreamReactor::session() const {
  std::lock_guard lock(mu_);
  return session_;
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
      End({grpc::StatusCode::INVALID_ARGUMENT, "attach: the first message must attach to a session"});
      return;
    }
    const grpc::Status status = Guarded([&] { HandleAttach(in_.attach()); });
    if (!status.ok()) {
      End(status);
      return;
    }
  } else if (in_.has_attach()) {
    End({grpc::StatusCode::INVALID_ARGUMENT, "attach: this stream is already attached"});
    return;
  } else {
    const grpc::Status status = Guarded([&] { session->OnEvent(in_.event(), arrival); });
    if (!status.ok()) {  // a bad event ends the session, with the message naming the field
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
  std::shared_ptr<Session> session = core_->FindSession(attach.session_id(), *principal_);
  {
    std::lock_guard lock(mu_);
    session_ = session;
  }
  session->Attach(this);
}

void SessionStreamReactor::OfferFrame(v1::Frame frame, Clock::time_point origin) {
  std::lock_guard lock(mu_);
  if (finished_ || finish_after_write_) return;
  if (!writing_) {
    frame.mutable_timings()->set_server_us(static_cast<std::uint32_t>(
        std::chrono::duration_cast<std::chrono::microseconds>(Clock::now() - origin).count()));
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

void SessionStreamReactor::SendNotice(v1::Notice::Level level, std::string message) {
  v1::ServerMessage out;
  out.mutable_notice()->set_level(level);
  out.mutable_notice()->set_message(std::move(message));
  SendMessage(std::move(out));
}

void SessionStreamReactor::SendState(v1::SessionState state) {
  v1::ServerMessage out;
  *out.mutable_state() = std::move(state);
  SendMessage(std::move(out));
}

void SessionStreamReactor::SendMessage(v1::ServerMessage message) {
  std::lock_guard lock(mu_);
  if (finished_ || finish_after_write_) return;
  if (writing_) {
    messages_.push_back(std::move(message));
    return;
  }
  StartWriteLocked(std::move(message), false);
}

bool SessionStreamReactor::SlotFull() const {
  std::lock_guard lock(mu_);
  return slot_.has_value() || finished_ || finish_after_write_.has_value();
}

void SessionStreamReactor::End(grpc::Status status) {
  std::lock_guard lock(mu_);
  if (finished_ || finish_after_write_) return;
  if (writing_) {
    finish_after_write_ = std::move(status);
  } else {
    FinishLocked(status);
  }
}

void SessionStreamReactor::EndSession(grpc::Status status) {
  {
    std::lock_guard lock(mu_);
    if (finished_ || finish_after_write_) return;
    // The client library's SessionStream reads this trailer (client-cpp/library/client.cpp).
    context_->AddTrailingMetadata("cinevol-session-ended", "1");
  }
  End(std::move(status));
}

std::uint64_t SessionStreamReactor::frames_sent() const {
  std::lock_guard lock(mu_);
  return sent_;
}

std::uint64_t SessionStreamReactor::frames_dropped() const {
  std::lock_guard lock(mu_);
  return dropped_;
}

void SessionStreamReactor::StartWriteLocked(v1::ServerMessage message, bool is_frame) {
  out_ = std::move(message);
  writing_ = true;
  writing_frame_ = is_frame;
  if (is_frame) write_started_ = Clock::now();
  StartWrite(&out_);  // gRPC runs OnWriteDone on its own thread, never inside this call
}

void SessionStreamReactor::FinishLocked(const grpc::Status& status) {
  finished_ = true;
  if (slot_) {  // never sent
    ++dropped_;
    ServerMetrics().FrameDropped();
  }
  slot_.reset();
  messages_.clear();
  Finish(status);
}

void SessionStreamReactor::OnWriteDone(bool ok) {
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
      FinishLocked(finish_after_write_.value_or(
          grpc::Status(grpc::StatusCode::UNAVAILABLE, "the stream to the client broke")));
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
      parked.frame.mutable_timings()->set_server_us(static_cast<std::uint32_t>(
          std::chrono::duration_cast<std::chrono::microseconds>(Clock::now() - parked.origin).count()));
      v1::ServerMessage out;
      *out.mutable_frame() = std::move(parked.frame);
      StartWriteLocked(std::move(out), true);
    }
    wake = session_;  // the slot has room: the session may render again
  }
  if (wake) wake->OnWritable(this);
}

void SessionStreamReactor::OnCancel() { End({grpc::StatusCode::CANCELLED, "the client went away"}); }

void SessionStreamReactor::OnDone() {
  core_->calls().Forget(watch_);
  if (std::shared_ptr<Session> session = this->session()) session->Detach(this);
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

}  // namespace cinevol::service

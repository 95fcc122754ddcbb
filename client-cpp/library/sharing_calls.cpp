// SessionWatch: one server-streaming call at a time and its reader thread,
// which follows the session to another server when its own goes.
#include "sharing_calls.h"

#include "client.h"

namespace cinevol {
namespace {

// The watch's server went, or lost the session: it may be elsewhere now.
bool MayHaveMoved(const grpc::Status& status) {
  return status.error_code() == grpc::StatusCode::UNAVAILABLE || status.error_code() == grpc::StatusCode::NOT_FOUND;
}

}  // namespace

SessionWatch::SessionWatch(std::vector<std::shared_ptr<grpc::Channel>> channels, std::string grant,
                           const std::string& token, std::chrono::seconds follow)
    : channels_(std::move(channels)), grant_(std::move(grant)), token_(token), follow_(follow) {
  thread_ = std::thread([this] { ReadAll(); });
}

SessionWatch::~SessionWatch() {
  Cancel();
  thread_.join();
}

bool SessionWatch::ReadFrom(std::size_t index, grpc::Status& status) {
  grpc::ClientContext context;
  if (!token_.empty()) context.AddMetadata("authorization", "Bearer " + token_);
  {
    std::lock_guard lock(mu_);
    if (cancelled_) return false;
    call_ = &context;
    current_ = index;
  }
  v1::WatchSessionRequest request;
  request.set_grant(grant_);
  auto reader = v1::SessionService::NewStub(channels_[index])->WatchSession(&context, request);
  bool any = false;
  for (v1::ServerMessage message; reader->Read(&message); any = true) {
    std::lock_guard lock(mu_);
    if (!any && following_) {  // found where the session moved
      ++follows_;
      following_ = false;
    }
    if (message.has_state()) state_ = message.state();
    inbox_.push_back(std::move(message));
    arrived_.notify_all();
  }
  status = reader->Finish();
  std::lock_guard lock(mu_);
  call_ = nullptr;
  return any;
}

void SessionWatch::ReadAll() {
  const std::size_t n = channels_.size();
  grpc::Status status;
  bool watched = false;  // some server has streamed the session to us
  std::size_t index = 0, misses = 0;
  auto give_up = std::chrono::steady_clock::now() + follow_;
  for (;;) {
    const bool streamed = ReadFrom(index, status);
    if (streamed) {
      watched = true;
      misses = 0;
      give_up = std::chrono::steady_clock::now() + follow_;
    } else {
      ++misses;
    }
    bool following = false;
    {
      std::lock_guard lock(mu_);
      if (cancelled_) break;
      if (streamed) following_ = MayHaveMoved(status);  // a revocation or the session's end stop here
      following = following_;
    }
    bool look_elsewhere = false;
    if (streamed) {
      look_elsewhere = following;
    } else if (following) {  // until the window closes: the owner's client restores the grant there
      look_elsewhere = !status.ok();
    } else if (!watched) {  // the first servers asked may not hold the session
      look_elsewhere =
          (MayHaveMoved(status) || status.error_code() == grpc::StatusCode::PERMISSION_DENIED) && misses < n;
    }
    if (!look_elsewhere || std::chrono::steady_clock::now() >= give_up) break;
    index = (index + 1) % n;
    if (misses > 0 && misses % n == 0) std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
  std::lock_guard lock(mu_);
  status_ = status;
  ended_ = true;
  arrived_.notify_all();
}

std::optional<v1::ServerMessage> SessionWatch::Next(std::chrono::milliseconds timeout) {
  std::unique_lock lock(mu_);
  arrived_.wait_for(lock, timeout, [&] { return !inbox_.empty() || ended_; });
  if (inbox_.empty()) return std::nullopt;
  v1::ServerMessage message = std::move(inbox_.front());
  inbox_.pop_front();
  return message;
}

std::unique_ptr<grpc::ClientContext> SessionWatch::Context() const {
  auto context = std::make_unique<grpc::ClientContext>();
  context->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
  if (!token_.empty()) context->AddMetadata("authorization", "Bearer " + token_);
  return context;
}

v1::SessionState SessionWatch::Send(const std::vector<v1::SessionEvent>& events) {
  v1::SendEventsRequest request;
  request.set_grant(grant_);
  for (const v1::SessionEvent& e : events) *request.add_events() = e;
  std::size_t index = 0;
  {
    std::lock_guard lock(mu_);
    index = current_;
  }
  v1::SendEventsResponse response;
  Check(v1::SessionService::NewStub(channels_[index])->SendEvents(Context().get(), request, &response));
  return response.state();
}

void SessionWatch::Cancel() {
  std::lock_guard lock(mu_);
  cancelled_ = true;
  if (call_) call_->TryCancel();
}

bool SessionWatch::ended() const {
  std::lock_guard lock(mu_);
  return ended_;
}

grpc::Status SessionWatch::status() const {
  std::lock_guard lock(mu_);
  return status_;
}

std::optional<v1::SessionState> SessionWatch::state() const {
  std::lock_guard lock(mu_);
  return state_;
}

int SessionWatch::follows() const {
  std::lock_guard lock(mu_);
  return follows_;
}

}  // namespace cinevol

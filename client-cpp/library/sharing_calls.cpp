// SessionWatch: one server-streaming call and its reader thread.
#include "sharing_calls.h"

#include "client.h"

namespace cinevol {

SessionWatch::SessionWatch(std::shared_ptr<grpc::Channel> channel, std::string grant, const std::string& token)
    : grant_(std::move(grant)), token_(token), stub_(v1::SessionService::NewStub(channel)) {
  if (!token_.empty()) context_.AddMetadata("authorization", "Bearer " + token_);
  v1::WatchSessionRequest request;
  request.set_grant(grant_);
  reader_ = stub_->WatchSession(&context_, request);
  thread_ = std::thread([this] { ReadAll(); });
}

SessionWatch::~SessionWatch() {
  Cancel();
  thread_.join();
}

void SessionWatch::ReadAll() {
  for (v1::ServerMessage message; reader_->Read(&message);) {
    std::lock_guard lock(mu_);
    if (message.has_state()) state_ = message.state();
    inbox_.push_back(std::move(message));
    arrived_.notify_all();
  }
  const grpc::Status status = reader_->Finish();
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
  v1::SendEventsResponse response;
  Check(stub_->SendEvents(Context().get(), request, &response));
  return response.state();
}

void SessionWatch::Cancel() { context_.TryCancel(); }

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

}  // namespace cinevol

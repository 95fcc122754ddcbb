// The viewer's network side: a worker thread for calls and events, the
// stream's reader for frames, a decoder thread for JPEG.
#include "viewer/connection.h"

#include <fmt/format.h>

#include <utility>

#include "script_player.h"

namespace cinevol::viewer {
namespace {

using Clock = std::chrono::steady_clock;

// Codes that say the server refused what we asked: retrying cannot help.
bool Refused(grpc::StatusCode code) {
  return code != grpc::StatusCode::UNAVAILABLE && code != grpc::StatusCode::DEADLINE_EXCEEDED &&
         code != grpc::StatusCode::ABORTED && code != grpc::StatusCode::CANCELLED &&
         code != grpc::StatusCode::INTERNAL && code != grpc::StatusCode::UNKNOWN;
}

std::string Describe(grpc::StatusCode code, const std::string& message) {
  switch (code) {
    case grpc::StatusCode::UNAUTHENTICATED: return "the server does not accept this token: " + message;
    case grpc::StatusCode::PERMISSION_DENIED: return "the server refused: " + message;
    case grpc::StatusCode::UNAVAILABLE: return "cannot reach the server: " + message;
    default: return message;  // it starts with its code
  }
}

constexpr auto kRetryEvery = std::chrono::seconds(2);

}  // namespace

Connection::Connection(ConnectionSettings settings)
    : settings_(std::move(settings)),
      worker_([this] { Work(); }),
      requester_([this] { Serve(Lane::kLong); }),
      quick_requester_([this] { Serve(Lane::kQuick); }),
      decoder_([this] { Decode(); }) {}

Connection::~Connection() {
  {
    std::scoped_lock lock(mu_, frame_mu_);  // no waiter misses it
    stopping_ = true;
  }
  wake_.notify_all();
  frame_arrived_.notify_all();
  worker_.join();
  requester_.join();
  quick_requester_.join();
  decoder_.join();
}

LinkStatus Connection::status() const {
  std::lock_guard lock(mu_);
  return status_;
}

std::optional<v1::CreateSessionResponse> Connection::session() const {
  std::lock_guard lock(mu_);
  return session_;
}

std::optional<v1::VolumeInfo> Connection::volume() const {
  std::lock_guard lock(mu_);
  return volume_;
}

void Connection::Post(v1::SessionEvent event) {
  {
    std::lock_guard lock(mu_);
    if (event.has_camera() && !events_.empty() && events_.back().has_camera()) {
      events_.back() = std::move(event);  // the newest camera wins
    } else {
      events_.push_back(std::move(event));
    }
  }
  wake_.notify_all();
}

void Connection::Request(std::function<void(Client&)> request, std::function<void(const std::string&)> done,
                         Lane lane) {
  {
    std::lock_guard lock(mu_);
    requests_[int(lane)].waiting.emplace_back(std::move(request), std::move(done));
  }
  wake_.notify_all();
}

std::string Connection::TakeWarning() {
  std::lock_guard lock(mu_);
  return std::exchange(warning_, {});
}

bool Connection::idle() const {
  std::lock_guard lock(mu_);
  auto quiet = [](const Requests& r) { return r.waiting.empty() && !r.running; };
  return events_.empty() && sending_ == 0 && quiet(requests_[0]) && quiet(requests_[1]);
}

std::optional<ViewFrame> Connection::TakeFrame() {
  std::lock_guard lock(frame_mu_);
  std::optional<ViewFrame> frame = std::move(decoded_);
  decoded_.reset();
  return frame;
}

std::optional<Clock::time_point> Connection::SentAt(std::uint64_t seq) const {
  std::lock_guard lock(mu_);
  const auto it = sent_at_.find(seq);
  if (it == sent_at_.end()) return std::nullopt;
  return it->second;
}

void Connection::SetStatus(LinkState state, std::string message) {
  std::lock_guard lock(mu_);
  status_ = {state, std::move(message)};
}

void Connection::Start() {
  if (status().state != LinkState::kReconnecting) {  // while retrying, the last error stays in view
    SetStatus(LinkState::kConnecting, "connecting to " + settings_.client.address);
  }
  auto client = std::make_shared<Client>(settings_.client);
  {
    std::lock_guard lock(mu_);
    client_ = client;
  }
  wake_.notify_all();  // requests may have waited for a connection
  // After the first start, the volume it resolved to (an upload is not sent again).
  v1::VolumeInfo volume;
  if (!resolved_volume_.empty()) {
    try {
      volume = client->DescribeVolume(resolved_volume_);
    } catch (const RpcError& e) {
      if (e.code() != grpc::StatusCode::NOT_FOUND) throw;  // a restarted server lost it: resolve again
    }
  }
  if (volume.id().empty()) volume = client->DescribeVolume(cli::ResolveVolume(*client, settings_.session).id());
  v1::CreateSessionRequest request = cli::SessionRequest(settings_.session, volume.id());
  if (carried_ && volume.id() == resolved_volume_) {
    *request.mutable_scene() = carried_->scene();
    *request.mutable_stream() = carried_->stream();
    *request.mutable_viewport() = carried_->viewport();
  }
  resolved_volume_ = volume.id();
  const v1::CreateSessionResponse created = client->CreateSession(request);
  StreamOptions options;
  options.on_message = [this](const v1::ServerMessage& m) {
    if (m.has_notice() && m.notice().level() == v1::Notice::WARNING) {
      std::lock_guard lock(mu_);
      warning_ = m.notice().message();
    }
    if (!m.has_frame()) return;
    {
      std::lock_guard lock(frame_mu_);
      encoded_ = m.frame();
      encoded_at_ = Clock::now();
    }
    frame_arrived_.notify_one();
  };
  stream_ = client->Attach(created.session_id(), options);
  {
    std::lock_guard lock(mu_);
    volume_ = volume;
    session_ = created;
    sent_at_.clear();
  }
  SetStatus(LinkState::kStreaming, fmt::format("{} on {}", volume.id(), created.device()));
}

bool Connection::SendPending() {
  std::unique_lock lock(mu_);
  while (!events_.empty()) {
    v1::SessionEvent event = std::move(events_.front());
    events_.pop_front();
    ++sending_;
    lock.unlock();
    const std::uint64_t seq = stream_->Send(event);
    lock.lock();
    --sending_;
    if (seq == 0) return false;  // the stream ended or is reconnecting: the event is dropped
    sent_at_[seq] = Clock::now();
    last_sent_ = seq;
    while (sent_at_.size() > 4096) sent_at_.erase(sent_at_.begin());
  }
  return true;
}

void Connection::Work() {
  auto next_try = Clock::now();
  std::unique_lock lock(mu_);
  while (!stopping_) {
    lock.unlock();
    if (!stream_ && Clock::now() >= next_try) {
      try {
        Start();
      } catch (const RpcError& e) {
        const bool refused = Refused(e.code());
        SetStatus(refused ? LinkState::kFailed : LinkState::kReconnecting,
                  Describe(e.code(), e.what()) + (refused ? "" : " (retrying)"));
        stream_.reset();
        next_try = refused ? Clock::time_point::max() : Clock::now() + kRetryEvery;
      } catch (const std::exception& e) {
        SetStatus(LinkState::kFailed, e.what());
        next_try = Clock::time_point::max();
      }
    } else if (stream_ && stream_->ended()) {
      const grpc::Status s = stream_->status();
      // NOT_FOUND here: the server no longer knows the session (it restarted).
      const bool refused = Refused(s.error_code()) && s.error_code() != grpc::StatusCode::NOT_FOUND;
      SetStatus(refused ? LinkState::kFailed : LinkState::kReconnecting,
                Describe(s.error_code(), fmt::format("{}: {}", StatusCodeName(s.error_code()), s.error_message())) +
                    (refused ? "" : " (starting a new session)"));
      if (auto state = stream_->state()) carried_ = std::move(state);
      stream_.reset();
      next_try = refused ? Clock::time_point::max() : Clock::now() + kRetryEvery;
    } else if (stream_) {
      SendPending();
    }
    lock.lock();
    wake_.wait_for(lock, std::chrono::milliseconds(20), [this] { return stopping_ || !events_.empty(); });
  }
  lock.unlock();
  if (stream_ && session_) {
    try {
      client_->CloseSession(session_->session_id());
    } catch (const std::exception&) {  // the server went first: nothing to close
    }
    stream_->Finish(std::chrono::seconds(2));
  }
  SetStatus(LinkState::kClosed, "closed");
}

void Connection::Serve(Lane lane) {
  Requests& mine = requests_[int(lane)];
  std::unique_lock lock(mu_);
  for (;;) {
    wake_.wait(lock, [&] { return stopping_ || (!mine.waiting.empty() && client_); });
    if (stopping_) return;
    auto [request, done] = std::move(mine.waiting.front());
    mine.waiting.pop_front();
    mine.running = true;
    const std::shared_ptr<Client> client = client_;  // a reconnect may replace it meanwhile
    lock.unlock();
    std::string error;
    try {
      request(*client);
    } catch (const RpcError& e) {
      error = Describe(e.code(), e.what());
    } catch (const std::exception& e) {
      error = e.what();
    }
    done(error);
    lock.lock();
    mine.running = false;
  }
}

void Connection::Decode() {
  std::unique_lock lock(frame_mu_);
  for (;;) {
    frame_arrived_.wait(lock, [this] { return encoded_.has_value() || stopping_; });
    if (!encoded_) return;
    v1::Frame frame = std::move(*encoded_);
    encoded_.reset();
    const Clock::time_point received = encoded_at_;
    lock.unlock();
    ViewFrame view;
    const auto start = Clock::now();
    try {
      view.image = DecodeFrame(frame);
    } catch (const std::exception& e) {
      SetStatus(LinkState::kStreaming, std::string("a frame could not be decoded: ") + e.what());
      lock.lock();
      continue;
    }
    view.decode_ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    view.image_bytes = EncodedImage(frame).size();
    frame.clear_image();
    view.info = std::move(frame);
    view.received = received;
    lock.lock();
    decoded_ = std::move(view);
  }
}

}  // namespace cinevol::viewer

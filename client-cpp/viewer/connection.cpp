// The viewer's network side: a worker thread for calls and events, the
// stream's reader (or a watch's) for frames, requesters for calls.
#include "viewer/connection.h"

#include <fmt/format.h>

#include <algorithm>
#include <utility>

#include "script_player.h"
#include "viewer/sharing_view.h"

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
    case grpc::StatusCode::UNAUTHENTICATED:
      return "the server does not accept this token: " + message;
    case grpc::StatusCode::PERMISSION_DENIED:
      return "the server refused: " + message;
    case grpc::StatusCode::UNAVAILABLE:
      return "cannot reach the server: " + message;
    default:
      return message;  // it starts with its code
  }
}

constexpr auto kRetryEvery = std::chrono::seconds(2);
constexpr std::size_t kMaxBatch = 64;         // events in one SendEvents (docs/api.md)
constexpr std::size_t kTicketsKept = 4096;  // where the newest events went; older ones count as dropped

// Whether an event waiting last is replaced by a newer one of its kind.
bool Replaces(const v1::SessionEvent& newer, const v1::SessionEvent& older) {
  return (newer.has_camera() && older.has_camera()) || (newer.has_pointer() && older.has_pointer());
}

}  // namespace

Connection::Connection(ConnectionSettings settings)
    : settings_(std::move(settings)),
      decoder_([this](const std::string& error) { SetStatus(LinkState::kStreaming, error); }),
      worker_([this] { Work(); }),
      requester_([this] { Serve(Lane::kLong); }),
      quick_requester_([this] { Serve(Lane::kQuick); }) {}

Connection::~Connection() {
  {
    std::lock_guard lock(mu_);  // no waiter misses it
    stopping_ = true;
  }
  wake_.notify_all();
  worker_.join();
  requester_.join();
  quick_requester_.join();
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

std::optional<v1::VolumeInfo> Connection::fused_volume() const {
  std::lock_guard lock(mu_);
  return fused_volume_;
}

std::uint64_t Connection::Post(v1::SessionEvent event) {
  std::uint64_t ticket = 0;
  {
    std::lock_guard lock(mu_);
    ticket = next_ticket_++;
    if (!events_.empty() && Replaces(event, events_.back().event)) {
      DeliveredLocked({events_.back().ticket}, 0);  // the newest camera (or pointer) wins
      events_.back() = {ticket, std::move(event)};
    } else {
      events_.push_back({ticket, std::move(event)});
    }
  }
  wake_.notify_all();
  return ticket;
}

Delivery Connection::DeliveryOf(std::uint64_t ticket) const {
  std::lock_guard lock(mu_);
  const auto it = delivered_.find(ticket);
  if (it != delivered_.end()) {
    const bool gone = it->second.seq == 0 || it->second.epoch != epoch_;  // a reattached stream numbers anew
    return gone ? Delivery{Delivery::kDropped, 0} : Delivery{Delivery::kSent, it->second.seq};
  }
  const bool waiting = std::any_of(events_.begin(), events_.end(), [&](const Queued& q) { return q.ticket == ticket; }) ||
                       std::find(sending_.begin(), sending_.end(), ticket) != sending_.end();
  // Not queued, not sent: older than the tickets kept, or posted to no stream.
  return waiting || ticket >= next_ticket_ ? Delivery{} : Delivery{Delivery::kDropped, 0};
}

void Connection::DeliveredLocked(const std::vector<std::uint64_t>& tickets, std::uint64_t seq) {
  for (std::uint64_t ticket : tickets) delivered_[ticket] = {seq, epoch_};
  while (delivered_.size() > kTicketsKept) delivered_.erase(delivered_.begin());
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
  return events_.empty() && sending_.empty() && quiet(requests_[0]) && quiet(requests_[1]);
}

std::optional<v1::SessionState> Connection::TakeState() {
  std::lock_guard lock(mu_);
  return std::exchange(state_, std::nullopt);
}

bool Connection::TakePointerRefused() {
  std::lock_guard lock(mu_);
  return std::exchange(pointer_refused_, false);
}

std::optional<ViewFrame> Connection::TakeFrame() { return decoder_.Take(); }

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
  if (watching()) return Watch(*client);
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
  request.mutable_stream()->set_frames_at_rendered_size(true);  // the screen stretches them
  if (carried_ && volume.id() == resolved_volume_) {
    *request.mutable_scene() = carried_->scene();
    *request.mutable_stream() = carried_->stream();
    *request.mutable_viewport() = carried_->viewport();
  }
  resolved_volume_ = volume.id();
  Fuse(*client, request);
  const v1::CreateSessionResponse created = client->CreateSession(request);
  std::optional<v1::VolumeInfo> fused;
  if (const std::string& id = created.scene().fusion().volume_id(); !id.empty()) fused = client->DescribeVolume(id);
  StreamOptions options;
  options.on_message = [this](const v1::ServerMessage& m) { OnMessage(m); };
  stream_ = client->Attach(created.session_id(), options);
  first_epoch_ = epoch_ + 1;  // nothing sent before counts on this stream
  {
    std::lock_guard lock(mu_);
    volume_ = volume;
    fused_volume_ = fused;
    session_ = created;
    sent_at_.clear();
  }
  SetStatus(LinkState::kStreaming, fmt::format("{} on {}", volume.id(), created.device()));
}

void Connection::Fuse(Client& client, v1::CreateSessionRequest& request) const {
  if (settings_.fuse.volume_id.empty() || request.scene().has_fusion()) return;
  v1::VolumeInfo fused;
  try {
    fused = client.DescribeVolume(settings_.fuse.volume_id);
  } catch (const RpcError& e) {
    // Which flag named it: "NOT_FOUND: --fuse: volume_id: no volume 'x'".
    const std::string what = e.what();  // "CODE: message", as RpcError writes it
    throw RpcError(grpc::Status(e.code(), "--fuse: " + what.substr(what.find(": ") + 2)));
  }
  if (!request.has_scene()) {  // a preset (or none: the volume's default) goes in the scene, its oneof's other side
    const std::string preset = request.preset();
    request.mutable_scene()->mutable_transfer_function()->set_preset(preset);
  }
  *request.mutable_scene()->mutable_fusion() = FusedStart(fused, settings_.fuse.align_by_patient);
}

void Connection::Watch(Client& client) {
  watch_ = client.Watch(settings_.grant);
  // The watch queues what it reads; this thread hands it on as a stream's reader does.
  watch_reader_ = std::jthread([this, watch = watch_.get()](std::stop_token stop) {
    while (!stop.stop_requested()) {
      if (const auto message = watch->Next(std::chrono::milliseconds(100))) {
        OnMessage(*message);
      } else if (watch->ended()) {
        return;
      }
    }
  });
  {
    std::lock_guard lock(mu_);
    sent_at_.clear();
  }
  // The grant's id names it; its secret is never shown.
  SetStatus(LinkState::kStreaming, fmt::format("watching a shared session (grant {})", GrantIdOf(settings_.grant)));
}

void Connection::OnMessage(const v1::ServerMessage& m) {
  if (m.has_notice() && m.notice().level() == v1::Notice::WARNING) {
    std::lock_guard lock(mu_);
    warning_ = m.notice().message();
  }
  if (m.has_state()) {
    std::lock_guard lock(mu_);
    state_ = m.state();
  }
  if (m.has_frame()) decoder_.Offer(m.frame());
}

std::optional<grpc::Status> Connection::Ended() const {
  if (stream_ && stream_->ended()) return stream_->status();
  if (watch_ && watch_->ended()) return watch_->status();
  return std::nullopt;
}

void Connection::Detach() {
  if (stream_) {
    if (auto state = stream_->state()) carried_ = std::move(state);
  }
  watch_reader_ = {};  // stops and joins it before its watch goes
  watch_.reset();
  stream_.reset();
}

bool Connection::Ending(const grpc::Status& s) {
  const std::string said = fmt::format("{}: {}", StatusCodeName(s.error_code()), s.error_message());
  if (watching()) {
    // A revoked or expired grant, a session that ended (OK: its owner closed
    // it; NOT_FOUND: it is gone): for good. A lost connection: watch again.
    const bool over = s.ok() || Refused(s.error_code());
    SetStatus(over ? LinkState::kFailed : LinkState::kReconnecting,
              s.ok() ? "the shared session has ended: " + s.error_message()
                     : Describe(s.error_code(), said) + (over ? "" : " (watching again)"));
    return !over;
  }
  // NOT_FOUND here: the server no longer knows the session (it restarted).
  const bool refused = Refused(s.error_code()) && s.error_code() != grpc::StatusCode::NOT_FOUND;
  SetStatus(refused ? LinkState::kFailed : LinkState::kReconnecting,
            Describe(s.error_code(), said) + (refused ? "" : " (starting a new session)"));
  return !refused;
}

bool Connection::SendPending() {
  if (watch_) {
    SendAsGrant();
    return true;
  }
  epoch_ = first_epoch_ + stream_->resumes() + stream_->failovers();
  std::unique_lock lock(mu_);
  while (!events_.empty()) {
    auto [ticket, event] = std::move(events_.front());
    events_.pop_front();
    sending_ = {ticket};
    lock.unlock();
    const std::uint64_t seq = stream_->Send(event);
    lock.lock();
    sending_.clear();
    DeliveredLocked({ticket}, seq);
    if (seq == 0) return false;  // the stream ended or is reconnecting: the event is dropped
    if (event.has_pointer() || event.has_measurements()) continue;  // no frame answers these: they change no picture
    sent_at_[seq] = Clock::now();
    last_sent_ = seq;
    while (sent_at_.size() > 4096) sent_at_.erase(sent_at_.begin());
  }
  return true;
}

// A grant holder's events, in batches: the session numbers them, and its
// answer says up to which one it applied. A refusal drops the batch: a
// viewer's pointer where its grant does not share it, or a viewer's drive
// (the UI sends none; the presenter may have changed meanwhile).
void Connection::SendAsGrant() {
  std::vector<v1::SessionEvent> batch;
  {
    std::lock_guard lock(mu_);
    while (!events_.empty() && batch.size() < kMaxBatch) {
      sending_.push_back(events_.front().ticket);
      batch.push_back(std::move(events_.front().event));
      events_.pop_front();
    }
    if (batch.empty()) return;
  }
  const bool drives = std::any_of(batch.begin(), batch.end(), [](const auto& e) { return !e.has_pointer(); });
  const Clock::time_point sent = Clock::now();
  std::optional<v1::SessionState> state;
  std::optional<RpcError> refused;
  try {
    state = watch_->Send(batch);
  } catch (const RpcError& e) {
    refused = e;
  }
  std::lock_guard lock(mu_);
  // The session numbers a grant holder's events: its answer says up to which one it applied.
  DeliveredLocked(sending_, refused ? 0 : state->last_event_seq());
  sending_.clear();
  if (refused) {
    if (drives || refused->code() != grpc::StatusCode::PERMISSION_DENIED) {
      warning_ = Describe(refused->code(), refused->what());
    } else {
      pointer_refused_ = true;
    }
  } else if (drives) {
    sent_at_[state->last_event_seq()] = sent;
    last_sent_ = state->last_event_seq();
  }
}

void Connection::Work() {
  auto next_try = Clock::now();
  std::unique_lock lock(mu_);
  while (!stopping_) {
    lock.unlock();
    if (!stream_ && !watch_ && Clock::now() >= next_try) {
      try {
        Start();
      } catch (const RpcError& e) {
        const bool refused = Refused(e.code());
        SetStatus(refused ? LinkState::kFailed : LinkState::kReconnecting,
                  Describe(e.code(), e.what()) + (refused ? "" : " (retrying)"));
        Detach();
        next_try = refused ? Clock::time_point::max() : Clock::now() + kRetryEvery;
      } catch (const std::exception& e) {
        SetStatus(LinkState::kFailed, e.what());
        next_try = Clock::time_point::max();
      }
    } else if (const std::optional<grpc::Status> ended = Ended()) {
      const bool again = Ending(*ended);
      Detach();
      next_try = again ? Clock::now() + kRetryEvery : Clock::time_point::max();
    } else if (stream_ || watch_) {
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
  if (watch_) watch_->Cancel();  // a watcher leaves; the session goes on for its owner
  Detach();
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

}  // namespace cinevol::viewer

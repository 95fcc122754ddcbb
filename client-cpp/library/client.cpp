// cinevol::Client over the generated stubs and its ServerPool.
#include "client.h"

#include <fmt/format.h>

#include "encode/image_codecs.h"
#include "server_pool.h"
#include "sharing_calls.h"
#include "snapshot_call.h"
#include "pacs_calls.h"
#include "volume_calls.h"

namespace cinevol {
namespace {

// Trailing metadata of a stream whose session the server ended.
constexpr char kSessionEndedTrailer[] = "cinevol-session-ended";
// Between attempts to reattach after a drop.
constexpr std::chrono::milliseconds kResumePause{200};

}  // namespace

std::string StatusCodeName(grpc::StatusCode code) {
  static const char* const kNames[] = {"OK", "CANCELLED", "UNKNOWN", "INVALID_ARGUMENT", "DEADLINE_EXCEEDED",
                                       "NOT_FOUND", "ALREADY_EXISTS", "PERMISSION_DENIED", "RESOURCE_EXHAUSTED",
                                       "FAILED_PRECONDITION", "ABORTED", "OUT_OF_RANGE", "UNIMPLEMENTED", "INTERNAL",
                                       "UNAVAILABLE", "DATA_LOSS", "UNAUTHENTICATED"};
  const int i = static_cast<int>(code);
  return i >= 0 && i < int(std::size(kNames)) ? kNames[i] : fmt::format("code {}", i);
}

RpcError::RpcError(const grpc::Status& status)
    : std::runtime_error(StatusCodeName(status.error_code()) + ": " + status.error_message()),
      code_(status.error_code()) {}

void Check(const grpc::Status& status) {
  if (!status.ok()) throw RpcError(status);
}

const std::string& EncodedImage(const v1::Frame& frame) { return frame.has_png() ? frame.png() : frame.jpeg(); }

RgbImage DecodeFrame(const v1::Frame& frame) {
  const std::string& encoded = EncodedImage(frame);
  const std::vector<std::uint8_t> bytes(encoded.begin(), encoded.end());
  const ImageRgb8 image = frame.has_png() ? DecodePng(bytes) : DecodeJpeg(bytes);
  return {image.width, image.height, image.bytes};
}

SessionStream::SessionStream(std::shared_ptr<ServerPool> pool, std::string session_id, StreamOptions options)
    : pool_(std::move(pool)), route_(std::move(session_id)), options_(std::move(options)) {
  {
    std::lock_guard lock(call_mu_);
    session_id_ = pool_->CurrentId(route_);
    channel_ = pool_->Channel(pool_->AddressOf(route_));
    stub_ = v1::SessionService::NewStub(channel_);
    Open();
  }
  reader_ = std::thread([this] { ReadAll(); });
}

SessionStream::~SessionStream() {
  Cancel();
  reader_.join();
}

void SessionStream::Open() {
  stream_.reset();  // the finished call goes before its context
  context_ = std::make_unique<grpc::ClientContext>();
  if (!pool_->options().token.empty()) context_->AddMetadata("authorization", "Bearer " + pool_->options().token);
  stream_ = stub_->StreamSession(context_.get());
  next_seq_ = 1;
  {
    std::lock_guard lock(mu_);
    sent_at_.clear();
  }
  v1::ClientMessage attach;
  attach.mutable_attach()->set_session_id(session_id_);
  stream_->Write(attach);
}

void SessionStream::Deliver(v1::ServerMessage message) {
  if (message.has_state()) {
    pool_->Adopt(route_, message.state());
    std::lock_guard lock(mu_);
    state_ = message.state();
  }
  if (options_.on_message) {
    options_.on_message(message);
    return;
  }
  std::lock_guard lock(mu_);
  inbox_.push_back(std::move(message));
  arrived_.notify_all();
}

void SessionStream::ReadAll() {
  grpc::Status status;
  // The end of the current drop's resume window; none while messages arrive.
  std::optional<std::chrono::system_clock::time_point> give_up;
  for (;;) {
    for (v1::ServerMessage message; stream_->Read(&message);) {
      give_up.reset();
      Deliver(std::move(message));
    }
    bool session_over = false;
    {
      std::lock_guard lock(call_mu_);  // Finish must not overlap a Write
      status = stream_->Finish();
      if (writes_closed_) break;
      // The server ended the session itself (closed, drained, failed): it
      // says so in the trailers (server/service/session_stream.cpp).
      session_over = context_->GetServerTrailingMetadata().count(kSessionEndedTrailer) > 0;
      reconnecting_ = true;
    }
    const grpc::StatusCode code = status.error_code();
    if (!give_up) give_up = std::chrono::system_clock::now() + options_.resume_timeout;
    if (options_.resume && code == grpc::StatusCode::UNAVAILABLE && !session_over && Resume(*give_up)) continue;
    const bool gone = code == grpc::StatusCode::UNAVAILABLE || code == grpc::StatusCode::NOT_FOUND;
    if (options_.failover && gone && Relocate(status)) {
      give_up.reset();
      continue;
    }
    if (session_over) pool_->Forget(route_);  // nothing left to route to or re-create
    break;
  }
  {
    std::lock_guard lock(call_mu_);
    writes_closed_ = true;
  }
  std::lock_guard lock(mu_);
  ended_ = true;
  status_ = status;
  arrived_.notify_all();
}

bool SessionStream::Resume(std::chrono::system_clock::time_point give_up) {
  // A server (or a proxy before it) that answers at once yet fails the
  // call is not asked again straight away.
  std::this_thread::sleep_for(std::min<std::chrono::system_clock::duration>(
      kResumePause, std::max<std::chrono::system_clock::duration>(give_up - std::chrono::system_clock::now(), {})));
  while (std::chrono::system_clock::now() < give_up) {
    if (channel_->WaitForConnected(std::min(give_up, std::chrono::system_clock::now() + std::chrono::seconds(1)))) {
      std::lock_guard lock(call_mu_);
      if (writes_closed_) return false;
      Open();
      pool_->Reattached(route_);
      reconnecting_ = false;
      std::lock_guard inbox_lock(mu_);
      ++resumes_;
      return true;
    }
    std::lock_guard lock(call_mu_);
    if (writes_closed_) return false;
  }
  return false;
}

bool SessionStream::Relocate(grpc::Status& status) {
  if (!pool_->CanRelocate(route_)) return false;
  std::string from;
  Placement placed;
  std::vector<v1::SessionEvent> replay;
  try {
    from = pool_->AddressOf(route_);
    placed = pool_->Relocate(route_, replay);
  } catch (const std::exception& e) {
    status = grpc::Status(status.error_code(),
                          fmt::format("{}; re-creating the session on another server failed: {}",
                                      status.error_message(), e.what()));
    return false;
  }
  {
    std::lock_guard lock(call_mu_);
    if (writes_closed_) return false;
    channel_ = pool_->Channel(placed.address);
    stub_ = v1::SessionService::NewStub(channel_);
    session_id_ = placed.response.session_id();
    Open();
    reconnecting_ = false;
  }
  for (v1::SessionEvent& event : replay) Send(std::move(event));  // the server applies them as it would have
  {
    std::lock_guard lock(mu_);
    ++failovers_;
  }
  v1::ServerMessage notice;
  notice.mutable_notice()->set_level(v1::Notice::INFO);
  notice.mutable_notice()->set_message(
      fmt::format("the session's server {} went away ({}): the session was created again from its last state on {} "
                  "as {}",
                  from, StatusCodeName(status.error_code()), placed.address, placed.response.session_id()));
  Deliver(std::move(notice));
  return true;
}

std::uint64_t SessionStream::Send(v1::SessionEvent event) {
  std::lock_guard lock(call_mu_);
  if (writes_closed_ || reconnecting_) return 0;
  const std::uint64_t seq = next_seq_++;
  event.set_seq(seq);
  v1::ClientMessage message;
  *message.mutable_event() = std::move(event);
  {
    std::lock_guard inbox_lock(mu_);
    sent_at_[seq] = std::chrono::steady_clock::now();
  }
  if (!stream_->Write(message)) return 0;
  pool_->Sent(route_, message.event());
  return seq;
}

std::optional<v1::SessionState> SessionStream::state() const {
  std::lock_guard lock(mu_);
  return state_;
}

std::optional<v1::ServerMessage> SessionStream::Next(std::chrono::milliseconds timeout) {
  std::unique_lock lock(mu_);
  arrived_.wait_for(lock, timeout, [&] { return !inbox_.empty() || ended_; });
  if (inbox_.empty()) return std::nullopt;
  v1::ServerMessage message = std::move(inbox_.front());
  inbox_.pop_front();
  return message;
}

std::chrono::steady_clock::time_point SessionStream::SentAt(std::uint64_t seq) const {
  std::lock_guard lock(mu_);
  auto it = sent_at_.find(seq);
  return it == sent_at_.end() ? std::chrono::steady_clock::time_point{} : it->second;
}

grpc::Status SessionStream::Finish(std::chrono::milliseconds timeout) {
  {
    std::lock_guard lock(call_mu_);
    if (!writes_closed_) {
      writes_closed_ = true;
      if (!reconnecting_) stream_->WritesDone();
    }
  }
  std::unique_lock lock(mu_);
  if (!arrived_.wait_for(lock, timeout, [&] { return ended_; })) {
    lock.unlock();
    Cancel();
    lock.lock();
    arrived_.wait(lock, [&] { return ended_; });
  }
  return status_;
}

void SessionStream::Cancel() {
  std::lock_guard lock(call_mu_);
  writes_closed_ = true;
  context_->TryCancel();
}

bool SessionStream::ended() const {
  std::lock_guard lock(mu_);
  return ended_;
}

grpc::Status SessionStream::status() const {
  std::lock_guard lock(mu_);
  return status_;
}

int SessionStream::resumes() const {
  std::lock_guard lock(mu_);
  return resumes_;
}

int SessionStream::failovers() const {
  std::lock_guard lock(mu_);
  return failovers_;
}

std::string SessionStream::session_id() const {
  std::lock_guard lock(call_mu_);
  return session_id_;
}

Client::Client(const ClientOptions& options) : pool_(std::make_shared<ServerPool>(options)) {}

std::shared_ptr<grpc::Channel> Client::channel() const { return pool_->Channel(pool_->home()); }

template <class Call>
auto Client::OnHome(const Call& call) {
  const std::string home = pool_->home();
  try {
    return call(home);
  } catch (const RpcError& e) {
    if (e.code() != grpc::StatusCode::UNAVAILABLE || !pool_->MoveHome(home)) throw;
  }
  return call(pool_->home());
}

std::vector<v1::VolumeInfo> Client::ListVolumes() {
  return OnHome([&](const std::string& home) { return VolumeCalls(*pool_, home).List(); });
}

v1::VolumeInfo Client::LoadVolume(const std::string& path, const std::string& series_uid,
                                  const std::string& orientation, bool resample_uneven) {
  return OnHome([&](const std::string& home) {
    VolumeOrigin origin;
    origin.home = home;
    origin.load.set_path(path);
    origin.load.set_series_uid(series_uid);
    origin.load.set_orientation(orientation);
    origin.load.set_resample_uneven(resample_uneven);
    v1::VolumeInfo info = VolumeCalls(*pool_, home).Load(origin.load);
    pool_->RememberVolume(info.id(), origin);
    return info;
  });
}

std::vector<std::string> Client::ListPacs() {
  return OnHome([&](const std::string& home) { return PacsCalls(*pool_, home).Names(); });
}

std::vector<v1::StudySummary> Client::SearchStudies(const v1::SearchStudiesRequest& request) {
  return OnHome([&](const std::string& home) { return PacsCalls(*pool_, home).SearchStudies(request); });
}

std::vector<v1::SeriesSummary> Client::SearchSeries(const std::string& pacs, const std::string& study_uid) {
  return OnHome([&](const std::string& home) { return PacsCalls(*pool_, home).SearchSeries(pacs, study_uid); });
}

v1::VolumeInfo Client::LoadSeries(const v1::LoadSeriesRequest& request,
                                  const std::function<void(const v1::LoadSeriesProgress&)>& on_progress) {
  return OnHome([&](const std::string& home) {
    VolumeOrigin origin;
    origin.home = home;
    origin.series = request;
    v1::VolumeInfo info = PacsCalls(*pool_, home).LoadSeries(request, on_progress);
    pool_->RememberVolume(info.id(), origin);
    return info;
  });
}

v1::StoredObject Client::StoreMeasurements(const std::string& session_id, const std::string& pacs) {
  v1::StoreMeasurementsRequest request;
  request.set_session_id(pool_->CurrentId(session_id));
  request.set_pacs(pacs);
  return PacsCalls(*pool_, pool_->AddressOf(session_id)).StoreMeasurements(request);  // where the session lives
}

v1::LoadMeasurementsResponse Client::LoadMeasurements(const v1::LoadMeasurementsRequest& request) {
  return OnHome([&](const std::string& home) { return PacsCalls(*pool_, home).LoadMeasurements(request); });
}

v1::LoadPresentationResponse Client::LoadPresentation(const v1::LoadPresentationRequest& request) {
  return OnHome([&](const std::string& home) { return PacsCalls(*pool_, home).LoadPresentation(request); });
}

v1::SliceImage Client::RenderFrame(const v1::RenderFrameRequest& request) {
  return OnHome([&](const std::string& home) { return PacsCalls(*pool_, home).RenderFrame(request); });
}

v1::VolumeInfo Client::UploadVolume(const std::filesystem::path& file, const std::string& orientation,
                                    std::size_t chunk_bytes) {
  return OnHome([&](const std::string& home) {
    VolumeOrigin origin;
    origin.home = home;
    origin.upload = std::filesystem::absolute(file);
    origin.upload_fields.set_orientation(orientation);
    v1::VolumeInfo info = VolumeCalls(*pool_, home).Upload(file, origin.upload_fields, chunk_bytes);
    pool_->RememberVolume(info.id(), origin);
    return info;
  });
}

v1::VolumeInfo Client::LoadLabels(const std::string& volume_id, const std::string& path,
                                  const std::string& table_path) {
  return OnHome([&](const std::string& home) {
    v1::VolumeInfo info = VolumeCalls(*pool_, home).LoadLabels(pool_->VolumeOn(home, volume_id), path, table_path);
    VolumeOrigin origin;
    origin.home = home;
    origin.labels_path = path;
    origin.labels_table_path = table_path;
    pool_->RememberLabels(volume_id, origin);
    return info;
  });
}

v1::VolumeInfo Client::UploadLabels(const std::string& volume_id, const std::filesystem::path& file,
                                    const std::filesystem::path& table) {
  return OnHome([&](const std::string& home) {
    v1::VolumeInfo info = VolumeCalls(*pool_, home).UploadLabels(pool_->VolumeOn(home, volume_id), file, table);
    VolumeOrigin origin;
    origin.home = home;
    origin.labels_upload = std::filesystem::absolute(file);
    if (!table.empty()) origin.labels_upload_table = std::filesystem::absolute(table);
    pool_->RememberLabels(volume_id, origin);
    return info;
  });
}

v1::VolumeInfo Client::DescribeVolume(const std::string& volume_id) {
  return OnHome(
      [&](const std::string& home) { return VolumeCalls(*pool_, home).Describe(pool_->VolumeOn(home, volume_id)); });
}

void Client::UnloadVolume(const std::string& volume_id) {
  OnHome([&](const std::string& home) {
    VolumeCalls(*pool_, home).Unload(pool_->KnownIdOn(home, volume_id));
    return 0;
  });
}

v1::CreateSessionResponse Client::CreateSession(const v1::CreateSessionRequest& request) {
  return pool_->CreateSession(request).response;
}

std::unique_ptr<SessionStream> Client::Attach(const std::string& session_id, StreamOptions options) {
  return std::make_unique<SessionStream>(pool_, session_id, std::move(options));
}

std::string Client::SessionAddress(const std::string& session_id) const { return pool_->AddressOf(session_id); }

v1::SnapshotResponse Client::Snapshot(v1::SnapshotRequest request, const SnapshotOptions& options) {
  auto stub = v1::SessionService::NewStub(pool_->Channel(pool_->AddressOf(request.session_id())));
  request.set_session_id(pool_->CurrentId(request.session_id()));
  try {
    return StreamStill(*stub, pool_->CallContext(std::nullopt), request, options, pool_->options().snapshot_silence);
  } catch (const RpcError& e) {
    if (e.code() != grpc::StatusCode::UNIMPLEMENTED) throw;
  }
  // A server from before StreamSnapshot: one unary call, with a deadline.
  const auto limit = options.timeout.count() > 0 ? options.timeout : pool_->options().call_timeout;
  v1::SnapshotResponse response;
  Check(stub->Snapshot(pool_->CallContext(limit).get(), request, &response));
  return response;
}

v1::Movie Client::RenderMovie(v1::MovieRequest request,
                              const std::function<void(const v1::MovieProgress&)>& on_progress) {
  auto stub = v1::SessionService::NewStub(pool_->Channel(pool_->AddressOf(request.session_id())));
  request.set_session_id(pool_->CurrentId(request.session_id()));
  auto context = pool_->CallContext(std::nullopt);  // a movie takes as long as its frames: progress says how long
  auto reader = stub->RenderMovie(context.get(), request);
  v1::MovieUpdate update;
  std::optional<v1::Movie> movie;
  while (reader->Read(&update)) {
    if (update.has_progress() && on_progress) on_progress(update.progress());
    if (update.has_movie()) movie = std::move(*update.mutable_movie());
  }
  Check(reader->Finish());
  if (!movie) throw RpcError({grpc::StatusCode::INTERNAL, "the server ended the movie without it"});
  return std::move(*movie);
}

v1::SessionState Client::SendEvents(const std::string& session_id, const std::vector<v1::SessionEvent>& events) {
  auto stub = v1::SessionService::NewStub(pool_->Channel(pool_->AddressOf(session_id)));
  v1::SendEventsRequest request;
  request.set_session_id(pool_->CurrentId(session_id));
  for (const v1::SessionEvent& event : events) *request.add_events() = event;
  v1::SendEventsResponse response;
  Check(stub->SendEvents(pool_->CallContext().get(), request, &response));
  return response.state();
}

void Client::CloseSession(const std::string& session_id) {
  auto stub = v1::SessionService::NewStub(pool_->Channel(pool_->AddressOf(session_id)));
  v1::CloseSessionRequest request;
  request.set_session_id(pool_->CurrentId(session_id));
  v1::CloseSessionResponse response;
  Check(stub->CloseSession(pool_->CallContext().get(), request, &response));
  pool_->Forget(session_id);
}

v1::SliceImage Client::RenderSlice(v1::SliceRequest request) {
  auto stub = v1::SessionService::NewStub(pool_->Channel(pool_->AddressOf(request.session_id())));
  request.set_session_id(pool_->CurrentId(request.session_id()));
  v1::SliceImage image;
  Check(stub->RenderSlice(pool_->CallContext().get(), request, &image));
  return image;
}

v1::PickResult Client::Pick(v1::PickRequest request) {
  auto stub = v1::SessionService::NewStub(pool_->Channel(pool_->AddressOf(request.session_id())));
  request.set_session_id(pool_->CurrentId(request.session_id()));
  v1::PickResult result;
  Check(stub->Pick(pool_->CallContext().get(), request, &result));
  return result;
}

v1::Grant Client::Share(v1::ShareSessionRequest request) {
  const std::string route = request.session_id();
  auto stub = v1::SessionService::NewStub(pool_->Channel(pool_->AddressOf(route)));
  request.set_session_id(pool_->CurrentId(route));
  v1::Grant grant;
  Check(stub->ShareSession(pool_->CallContext().get(), request, &grant));
  pool_->RememberGrant(route, request, grant);  // restored where a failover moves the session
  return grant;
}

std::vector<v1::Grant> Client::ListShares(const std::string& session_id) {
  auto stub = v1::SessionService::NewStub(pool_->Channel(pool_->AddressOf(session_id)));
  v1::ListSharesRequest request;
  request.set_session_id(pool_->CurrentId(session_id));
  v1::ListSharesResponse response;
  Check(stub->ListShares(pool_->CallContext().get(), request, &response));
  return {response.grants().begin(), response.grants().end()};
}

std::uint32_t Client::RevokeShare(const std::string& session_id, const std::string& grant_id) {
  auto stub = v1::SessionService::NewStub(pool_->Channel(pool_->AddressOf(session_id)));
  v1::RevokeShareRequest request;
  request.set_session_id(pool_->CurrentId(session_id));
  request.set_grant_id(grant_id);
  v1::RevokeShareResponse response;
  Check(stub->RevokeShare(pool_->CallContext().get(), request, &response));
  return response.streams_ended();
}

std::string Client::HandOver(v1::HandOverRequest request) {
  auto stub = v1::SessionService::NewStub(pool_->Channel(pool_->AddressOf(request.session_id())));
  if (!request.session_id().empty()) request.set_session_id(pool_->CurrentId(request.session_id()));
  v1::HandOverResponse response;
  Check(stub->HandOver(pool_->CallContext().get(), request, &response));
  return response.presenter();
}

std::unique_ptr<SessionWatch> Client::Watch(const std::string& grant) {
  std::vector<std::shared_ptr<grpc::Channel>> channels;
  for (const std::string& server : pool_->Servers()) channels.push_back(pool_->Channel(server));
  return std::make_unique<SessionWatch>(std::move(channels), grant, pool_->options().token);
}

v1::ServerStatus Client::Status() {
  return OnHome([&](const std::string& home) {
    auto stub = v1::ServerService::NewStub(pool_->Channel(home));
    v1::ServerStatus status;
    Check(stub->GetStatus(pool_->CallContext().get(), {}, &status));
    return status;
  });
}

}  // namespace cinevol

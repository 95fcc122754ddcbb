// cinevol::Client over the generated stubs.
#include "client.h"

#include <fmt/format.h>

#include <fstream>
#include <iterator>
#include <stdexcept>

#include "encode/image_codecs.h"

namespace cinevol {
namespace {

constexpr int kMaxReceiveBytes = 512 << 20;  // a 4K EXR snapshot is about 100 MB

void Check(const grpc::Status& status) {
  if (!status.ok()) throw RpcError(status);
}

void AddToken(grpc::ClientContext& context, const std::string& token) {
  if (!token.empty()) context.AddMetadata("authorization", "Bearer " + token);
}

std::string ReadPem(const std::filesystem::path& file, const char* what) {
  std::ifstream in(file, std::ios::binary);
  if (!in || std::filesystem::is_directory(file)) {
    throw std::invalid_argument(fmt::format("{} {}: cannot read the file", what, file.string()));
  }
  std::string text(std::istreambuf_iterator<char>(in), {});
  if (text.find("-----BEGIN ") == std::string::npos) {
    throw std::invalid_argument(fmt::format("{} {}: not a PEM file", what, file.string()));
  }
  return text;
}

std::shared_ptr<grpc::ChannelCredentials> Credentials(const ClientOptions& options) {
  if (options.tls_ca.empty() && options.tls_cert.empty() && options.tls_key.empty()) {
    return grpc::InsecureChannelCredentials();
  }
  if (options.tls_cert.empty() != options.tls_key.empty()) {
    throw std::invalid_argument("tls_cert (--tls-cert) and tls_key (--tls-key) go together: give both");
  }
  grpc::SslCredentialsOptions ssl;
  if (!options.tls_ca.empty()) ssl.pem_root_certs = ReadPem(options.tls_ca, "--tls-ca");
  if (!options.tls_cert.empty()) {
    ssl.pem_cert_chain = ReadPem(options.tls_cert, "--tls-cert");
    ssl.pem_private_key = ReadPem(options.tls_key, "--tls-key");
  }
  return grpc::SslCredentials(ssl);
}

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

const std::string& EncodedImage(const v1::Frame& frame) { return frame.has_png() ? frame.png() : frame.jpeg(); }

RgbImage DecodeFrame(const v1::Frame& frame) {
  const std::string& encoded = EncodedImage(frame);
  const std::vector<std::uint8_t> bytes(encoded.begin(), encoded.end());
  const ImageRgb8 image = frame.has_png() ? DecodePng(bytes) : DecodeJpeg(bytes);
  return {image.width, image.height, image.bytes};
}

SessionStream::SessionStream(std::shared_ptr<grpc::Channel> channel, std::string session_id, std::string token,
                             StreamOptions options)
    : channel_(std::move(channel)),
      stub_(v1::SessionService::NewStub(channel_)),
      session_id_(std::move(session_id)),
      token_(std::move(token)),
      options_(std::move(options)) {
  {
    std::lock_guard lock(call_mu_);
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
  AddToken(*context_, token_);
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
  for (;;) {
    for (v1::ServerMessage message; stream_->Read(&message);) Deliver(std::move(message));
    {
      std::lock_guard lock(call_mu_);  // Finish must not overlap a Write
      status = stream_->Finish();
      if (!options_.resume || writes_closed_ || status.error_code() != grpc::StatusCode::UNAVAILABLE) break;
      reconnecting_ = true;
    }
    if (!Resume()) break;
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

bool SessionStream::Resume() {
  const auto deadline = std::chrono::system_clock::now() + options_.resume_timeout;
  while (std::chrono::system_clock::now() < deadline) {
    if (channel_->WaitForConnected(std::min(deadline, std::chrono::system_clock::now() + std::chrono::seconds(1)))) {
      std::lock_guard lock(call_mu_);
      if (writes_closed_) return false;
      Open();
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
  return stream_->Write(message) ? seq : 0;
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

Client::Client(const ClientOptions& options) : options_(options) {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(kMaxReceiveBytes);
  const bool tls = !options.tls_ca.empty() || !options.tls_cert.empty();
  channel_ = grpc::CreateCustomChannel(options.address, Credentials(options), args);
  if (!channel_->WaitForConnected(std::chrono::system_clock::now() + options.connect_timeout)) {
    throw RpcError({grpc::StatusCode::UNAVAILABLE,
                    fmt::format("cannot reach cinevol-server at {} within {} s{}", options.address,
                                options.connect_timeout.count() / 1000.0,
                                tls ? " (over TLS: is the server's certificate signed by --tls-ca, for this "
                                      "address, and does the server accept the client certificate?)"
                                    : " (is it running? a server with TLS needs --tls-ca)")});
  }
  volumes_ = v1::VolumeService::NewStub(channel_);
  sessions_ = v1::SessionService::NewStub(channel_);
  server_ = v1::ServerService::NewStub(channel_);
}

std::unique_ptr<grpc::ClientContext> Client::CallContext() const {
  auto context = std::make_unique<grpc::ClientContext>();
  context->set_deadline(std::chrono::system_clock::now() + options_.call_timeout);
  AddToken(*context, options_.token);
  return context;
}

std::vector<v1::VolumeInfo> Client::ListVolumes() {
  v1::ListVolumesResponse response;
  Check(volumes_->ListVolumes(CallContext().get(), {}, &response));
  return {response.volumes().begin(), response.volumes().end()};
}

v1::VolumeInfo Client::LoadVolume(const std::string& path, const std::string& series_uid) {
  v1::LoadVolumeRequest request;
  request.set_path(path);
  request.set_series_uid(series_uid);
  v1::VolumeInfo info;
  Check(volumes_->LoadVolume(CallContext().get(), request, &info));
  return info;
}

v1::VolumeInfo Client::UploadVolume(const std::filesystem::path& file, std::size_t chunk_bytes) {
  return Upload(file, {}, chunk_bytes);
}

v1::VolumeInfo Client::LoadLabels(const std::string& volume_id, const std::string& path,
                                  const std::string& table_path) {
  v1::LoadLabelsRequest request;
  request.set_volume_id(volume_id);
  request.set_path(path);
  request.set_table_path(table_path);
  v1::VolumeInfo info;
  Check(volumes_->LoadLabels(CallContext().get(), request, &info));
  return info;
}

v1::VolumeInfo Client::UploadLabels(const std::string& volume_id, const std::filesystem::path& file,
                                    const std::filesystem::path& table) {
  v1::UploadVolumeChunk::Header header;
  header.set_labels_for(volume_id);
  if (!table.empty()) {
    std::ifstream in(table, std::ios::binary);
    if (!in) throw std::runtime_error(fmt::format("{}: cannot open", table.string()));
    header.set_label_table(std::string(std::istreambuf_iterator<char>(in), {}));
  }
  return Upload(file, header, 1 << 20);
}

v1::VolumeInfo Client::Upload(const std::filesystem::path& file, v1::UploadVolumeChunk::Header fields,
                              std::size_t chunk_bytes) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error(fmt::format("{}: cannot open", file.string()));
  v1::VolumeInfo info;
  auto context = CallContext();
  auto writer = volumes_->UploadVolume(context.get(), &info);
  v1::UploadVolumeChunk header;
  fields.set_file_name(file.filename().string());
  fields.set_size_bytes(std::filesystem::file_size(file));
  *header.mutable_header() = std::move(fields);
  bool open = writer->Write(header);
  std::string buffer(chunk_bytes, '\0');
  while (open && in) {
    in.read(buffer.data(), std::streamsize(buffer.size()));
    if (in.gcount() == 0) break;
    v1::UploadVolumeChunk chunk;
    chunk.set_data(buffer.data(), std::size_t(in.gcount()));
    open = writer->Write(chunk);
  }
  writer->WritesDone();
  Check(writer->Finish());
  return info;
}

v1::VolumeInfo Client::DescribeVolume(const std::string& volume_id) {
  v1::DescribeVolumeRequest request;
  request.set_volume_id(volume_id);
  v1::VolumeInfo info;
  Check(volumes_->DescribeVolume(CallContext().get(), request, &info));
  return info;
}

void Client::UnloadVolume(const std::string& volume_id) {
  v1::UnloadVolumeRequest request;
  request.set_volume_id(volume_id);
  v1::UnloadVolumeResponse response;
  Check(volumes_->UnloadVolume(CallContext().get(), request, &response));
}

v1::CreateSessionResponse Client::CreateSession(const v1::CreateSessionRequest& request) {
  v1::CreateSessionResponse response;
  Check(sessions_->CreateSession(CallContext().get(), request, &response));
  return response;
}

std::unique_ptr<SessionStream> Client::Attach(const std::string& session_id, StreamOptions options) {
  return std::make_unique<SessionStream>(channel_, session_id, options_.token, std::move(options));
}

v1::SnapshotResponse Client::Snapshot(const v1::SnapshotRequest& request) {
  v1::SnapshotResponse response;
  Check(sessions_->Snapshot(CallContext().get(), request, &response));
  return response;
}

void Client::CloseSession(const std::string& session_id) {
  v1::CloseSessionRequest request;
  request.set_session_id(session_id);
  v1::CloseSessionResponse response;
  Check(sessions_->CloseSession(CallContext().get(), request, &response));
}

v1::ServerStatus Client::Status() {
  v1::ServerStatus status;
  Check(server_->GetStatus(CallContext().get(), {}, &status));
  return status;
}

}  // namespace cinevol

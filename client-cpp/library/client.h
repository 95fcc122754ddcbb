// cinevol::Client: the C++ client of cinevol-server. Connects, manages
// volumes and sessions with unary calls (each bounded by a deadline), and
// attaches to a session's stream: events go out with increasing sequence
// numbers, frames, notices and the session's state come back through Next()
// or a callback, and a dropped connection is resumed while the server still
// holds the session.
// Given several servers (one deployment's pods), it places each new session
// where there is most room and, when a session's server goes away, creates
// the session again on another from its last state (server_pool.h).
//
//   cinevol::Client client({.address = "127.0.0.1:50051"});
//   auto created = client.CreateSession(request);
//   auto stream = client.Attach(created.session_id());
//   stream->Send(camera_event);
//   while (auto message = stream->Next(std::chrono::seconds(1))) { ... }
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "cinevol/v1/service.grpc.pb.h"
#include "client_options.h"

namespace cinevol {

// A frame's pixels: 8-bit sRGB, rows top to bottom.
struct RgbImage {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  // width * height * 3
};

// A frame's encoded image: its JPEG, or its PNG (a final frame, where the
// stream's final_format asks for one).
const std::string& EncodedImage(const v1::Frame& frame);
// Decodes a frame's image; throws std::runtime_error when it is not one.
RgbImage DecodeFrame(const v1::Frame& frame);

struct StreamOptions {
  // Called on the stream's reader thread with every message from the server;
  // when set, Next() returns nothing. It must not block for long.
  std::function<void(const v1::ServerMessage&)> on_message;
  // After a dropped connection (UNAVAILABLE), attach again while the server
  // still holds the session; sequence numbers start again at 1.
  bool resume = true;
  // How long one drop may last, reconnecting included; past it, a session
  // this client created moves (failover below), so this need not be long.
  std::chrono::milliseconds resume_timeout{5000};
  // When the session's server is gone (it cannot be resumed: unreachable for
  // resume_timeout, draining, or restarted without it), create the session
  // again from its last state (the scene it was created with, changed by
  // every event sent since) on another of the Client's servers and go on
  // there: an INFO notice says so, sequence numbers start again at 1, and
  // the Client's calls for the session follow it. Only for sessions this
  // Client created.
  bool failover = true;
};

// How Client::Snapshot waits for a still. A still has no fixed deadline:
// its cost grows with pixels and samples (minutes on a CPU server at 720p
// and 256 spp), so the client follows the server's progress instead and
// gives up only when the server falls silent (ClientOptions::
// snapshot_silence), when `timeout` passes, or when `cancel` is raised.
struct SnapshotOptions {
  // The whole still, from the call to the image; 0: no limit.
  std::chrono::milliseconds timeout{0};
  // Called on the calling thread with each progress report (the first, with
  // no samples done, as soon as the server takes the still; then about one
  // a second).
  std::function<void(const v1::SnapshotProgress&)> on_progress;
  // Raised by another thread: the call is cancelled (RpcError CANCELLED)
  // within a tenth of a second, and the server stops rendering.
  const std::atomic<bool>* cancel = nullptr;
};

// "64/256 spp, 40 s, about 2m00s left": a still's progress for people.
std::string DescribeProgress(const v1::SnapshotProgress& progress);

class ServerPool;
class SessionWatch;

// One attached session stream. A thread reads the server's messages into a
// queue (or hands them to on_message); Next takes them in order.
class SessionStream {
 public:
  // Attaches to session `session_id` of `pool` (where it lives).
  SessionStream(std::shared_ptr<ServerPool> pool, std::string session_id, StreamOptions options);
  ~SessionStream();  // cancels the call if it is still open
  SessionStream(const SessionStream&) = delete;
  SessionStream& operator=(const SessionStream&) = delete;

  // Sends `event` with the next sequence number (1, 2, ...) and returns it,
  // or 0 when it could not be sent (the stream has ended or is reconnecting).
  std::uint64_t Send(v1::SessionEvent event);
  // The next message, waiting up to `timeout`; nullopt on timeout or once
  // the stream has ended and every message was taken (then see status()).
  std::optional<v1::ServerMessage> Next(std::chrono::milliseconds timeout);
  // When event `seq` of the current connection went out, for latency.
  std::chrono::steady_clock::time_point SentAt(std::uint64_t seq) const;
  // Closes the sending side and waits up to `timeout` for the server's status.
  grpc::Status Finish(std::chrono::milliseconds timeout);
  // Drops the call, as a client that goes away does (no resume).
  void Cancel();
  bool ended() const;
  grpc::Status status() const;  // OK until the stream ends
  int resumes() const;          // times the stream reattached after a drop
  int failovers() const;        // times the session was re-created on another server
  std::string session_id() const;  // the session's id now (it changes with a failover)
  // The session's state as the server last sent it (ServerMessage.state):
  // what it renders, events applied; nullopt before the first.
  std::optional<v1::SessionState> state() const;

 private:
  void Open();  // a new call that attaches; call_mu_ held
  void ReadAll();
  bool Resume(std::chrono::system_clock::time_point give_up);  // reattaches after a drop; false when it cannot
  bool Relocate(grpc::Status& status);  // re-creates the session elsewhere; false (status says why) when it cannot
  void Deliver(v1::ServerMessage message);

  const std::shared_ptr<ServerPool> pool_;
  const std::string route_;  // the session's first id: the pool knows it by it
  const StreamOptions options_;

  mutable std::mutex call_mu_;  // the call, its write side and where it goes
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::SessionService::Stub> stub_;
  std::string session_id_;
  std::unique_ptr<grpc::ClientContext> context_;
  std::unique_ptr<grpc::ClientReaderWriter<v1::ClientMessage, v1::ServerMessage>> stream_;
  bool writes_closed_ = false;  // by Finish or Cancel: no resume
  bool reconnecting_ = false;
  std::uint64_t next_seq_ = 1;

  mutable std::mutex mu_;  // what the reader delivers
  std::condition_variable arrived_;
  std::deque<v1::ServerMessage> inbox_;
  std::map<std::uint64_t, std::chrono::steady_clock::time_point> sent_at_;
  bool ended_ = false;
  grpc::Status status_;
  int resumes_ = 0;
  int failovers_ = 0;
  std::optional<v1::SessionState> state_;
  std::thread reader_;
};

class Client {
 public:
  // Connects (to the first of options.address's servers that answers);
  // throws RpcError(UNAVAILABLE) when none can be reached within
  // options.connect_timeout (a TLS handshake that fails included), and
  // std::invalid_argument when a TLS file cannot be read.
  explicit Client(const ClientOptions& options);

  // Volume calls go to the first server that answered (with several, to
  // another when it stops answering); a volume loaded or uploaded here is
  // loaded or uploaded again on another server where a session of it goes.
  std::vector<v1::VolumeInfo> ListVolumes();
  // `orientation` ("LPI") overrides the file's (docs/volumes-and-scenes.md);
  // `resample_uneven` resamples a DICOM series with uneven slice gaps instead
  // of refusing it.
  v1::VolumeInfo LoadVolume(const std::string& path, const std::string& series_uid = {},
                            const std::string& orientation = {}, bool resample_uneven = false);
  v1::VolumeInfo UploadVolume(const std::filesystem::path& file, const std::string& orientation = {},
                              std::size_t chunk_bytes = 1 << 20);
  // A segmentation for a loaded volume: a label volume on the server (under
  // its data roots) or a local file, each with an optional label table.
  v1::VolumeInfo LoadLabels(const std::string& volume_id, const std::string& path, const std::string& table_path = {});
  v1::VolumeInfo UploadLabels(const std::string& volume_id, const std::filesystem::path& file,
                              const std::filesystem::path& table = {});
  v1::VolumeInfo DescribeVolume(const std::string& volume_id);

  // The PACS the server names (--pacs), and what they hold (docs/pacs.md).
  std::vector<std::string> ListPacs();
  std::vector<v1::StudySummary> SearchStudies(const v1::SearchStudiesRequest& request);
  std::vector<v1::SeriesSummary> SearchSeries(const std::string& pacs, const std::string& study_uid);
  // A series from PACS `request.pacs()`, held as this caller's volume;
  // `on_progress` hears how far it came.
  v1::VolumeInfo LoadSeries(const v1::LoadSeriesRequest& request,
                            const std::function<void(const v1::LoadSeriesProgress&)>& on_progress = {});
  void UnloadVolume(const std::string& volume_id);
  // A session's measurements stored on PACS `pacs` as a DICOM SR measurement
  // report, into the study of the session's volume (which came from a PACS);
  // and a report read back as measurements (docs/pacs.md). A presentation
  // state read back as the scene it renders and the series it presents. A
  // frame of an image of a series this caller loaded, on its own plane and
  // grid (Supplement 174's rendered frame), bounded by call_timeout.
  v1::StoredObject StoreMeasurements(const std::string& session_id, const std::string& pacs);
  v1::LoadMeasurementsResponse LoadMeasurements(const v1::LoadMeasurementsRequest& request);
  v1::LoadPresentationResponse LoadPresentation(const v1::LoadPresentationRequest& request);
  v1::SliceImage RenderFrame(const v1::RenderFrameRequest& request);

  // With several servers, on the one with the most room (ServerStatus).
  // The session's calls below go where it lives (CreateSessionResponse's
  // address), and follow it when a stream's failover moves it.
  v1::CreateSessionResponse CreateSession(const v1::CreateSessionRequest& request);
  std::unique_ptr<SessionStream> Attach(const std::string& session_id, StreamOptions options = {});
  // Where session `session_id`'s calls go now (it changes with a failover).
  std::string SessionAddress(const std::string& session_id) const;
  // A still of the session's current state (StreamSnapshot; a server
  // without it gets the unary Snapshot, bounded by options.timeout or else
  // call_timeout). Throws RpcError: DEADLINE_EXCEEDED saying what ran out
  // (the timeout, or the server's silence), how far the still came and what
  // to do; CANCELLED when the session ended under it, saying why.
  v1::SnapshotResponse Snapshot(v1::SnapshotRequest request, const SnapshotOptions& options = {});
  // A movie of the session's view along a path (RenderMovie; docs/movies.md): `on_progress` with each report (the
  // first as soon as the server takes it), the MP4 once its last frame is in. No deadline: it lasts as long as its
  // frames take; the caller stops it by ending the process or the session.
  v1::Movie RenderMovie(v1::MovieRequest request, const std::function<void(const v1::MovieProgress&)>& on_progress = {});
  void CloseSession(const std::string& session_id);
  // The reading calls (docs/reading.md), bounded by call_timeout: a slice of
  // the session's volume as a PNG with its geometry, and what lies under a
  // pixel of the session's viewport.
  // Events for a session without a stream (SendEvents): the state after them.
  v1::SessionState SendEvents(const std::string& session_id, const std::vector<v1::SessionEvent>& events);
  v1::SliceImage RenderSlice(v1::SliceRequest request);
  v1::PickResult Pick(v1::PickRequest request);
  // Sharing (docs/sharing.md). The owner's calls: a grant (its secret is in
  // this answer only), the session's grants, a revocation (the number of
  // streams it ended), the presenter role handed over (request.grant_id
  // empty: back to the owner; with request.grant, by the presenter).
  v1::Grant Share(v1::ShareSessionRequest request);
  std::vector<v1::Grant> ListShares(const std::string& session_id);
  std::uint32_t RevokeShare(const std::string& session_id, const std::string& grant_id);
  std::string HandOver(v1::HandOverRequest request);
  // Watches a shared session by a grant's secret, on the first server that
  // answered, following it to the others when a failover moves it; this
  // client's token goes with it (a principal's grant needs it).
  std::unique_ptr<SessionWatch> Watch(const std::string& grant);
  // The status of the first server that answered.
  v1::ServerStatus Status();

  // The channel to the first server that answered.
  std::shared_ptr<grpc::Channel> channel() const;

 private:
  // call(home server), and once more on another server when the home does
  // not answer (UNAVAILABLE) and another does.
  template <class Call>
  auto OnHome(const Call& call);

  std::shared_ptr<ServerPool> pool_;
};

}  // namespace cinevol

// What the three services share: the volumes, the devices (one scheduler
// per GPU, or one for the CPU), the encoder, loader and setup pools, the
// sessions and the limits. The gRPC service classes are thin shells over it.
#pragma once

#include <grpcpp/support/status.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "cinevol/v1/service.pb.h"
#include "device/device.h"
#include "runtime/pacs_directory.h"
#include "runtime/scheduler.h"
#include "runtime/session.h"
#include "runtime/task_pool.h"
#include "runtime/volume_registry.h"
#include "scene/session_state.h"
#include "service/auth.h"
#include "service/call_watch.h"
#include "service/connection_limits.h"
#include "service/sharing.h"
#include "service/tls.h"

namespace cinevol::service {

// SendEvents' batch at most (service.proto): larger ones are INVALID_ARGUMENT.
inline constexpr int kMaxEventsPerCall = 64;

// Settings of a server; `cinevol-server --help` documents each, and
// docs/security.md gives the limits' defaults and why.
struct ServerOptions {
  std::string listen = "127.0.0.1:50051";
  Backend backend = Backend::kAuto;
  std::vector<int> devices;                       // GPU ids; empty: every usable GPU
  std::vector<std::filesystem::path> data_roots;  // where clients may load volumes from
  std::vector<std::string> volumes;               // preloaded; empty: phantom:head
  int workers_per_gpu = 16;                       // each its own CUDA stream
  // How workers wait for their GPU (device/device.h): yield measured best
  // with one session and with 128 (docs/performance.md, issue 61).
  GpuWait gpu_wait = GpuWait::kYield;
  // Frames rendering at once on a GPU render at most this many pixels
  // together: four 720p frames, or sixteen interactive ones at half size.
  std::int64_t pixels_in_flight_per_gpu = 4 * 1280 * 720;
  std::vector<pacs::PacsConfig> pacs;                     // --pacs NAME=URL, with the --pacs-* settings
  std::filesystem::path pacs_credentials;                 // --pacs-credentials FILE; empty: none
  int encode_threads = 0;                                 // encodes at once on the compute pool; 0: one per worker
  JpegEncoderKind jpeg_encoder = JpegEncoderKind::kAuto;  // --jpeg-encoder: nvJPEG on the GPU where it loads
  int max_sessions = 64;
  int max_sessions_per_principal = 16;
  // [0; 1000] frames a second every session on a GPU must keep when another
  // joins: a new session is refused (RESOURCE_EXHAUSTED) where, by the pixels
  // a second that GPU was seen to render while busy, round-robin would give
  // each fewer (Scheduler::Admits). 0: no such check. CPU servers never check.
  double min_session_fps = 30;
  int max_grants_per_principal = 32;            // shares a principal has made and not revoked (docs/sharing.md)
  std::uint64_t max_total_pixels = 40'000'000;  // viewport pixels of every session together
  VolumeLimits volume_limits;
  int max_uploads_per_principal = 2;       // at once
  double upload_idle_seconds = 30;         // an upload that sends nothing this long ends
  double first_message_seconds = 10;       // a call that sends no first message this long ends
  double call_seconds = 60;                // a unary call's work (a slice, a search, a framing) at most
  double detached_session_seconds = 60;    // a detached session waits this long for a new attach
  double unattached_session_seconds = 15;  // a session never attached waits this long
  double drain_seconds = 10;               // SIGTERM to exit, whatever is in flight
  SessionLimits limits;
  ConnectionLimits connections;
  std::string port_file;              // written with the bound port once listening
  std::filesystem::path auth_tokens;  // "TOKEN PRINCIPAL" lines; empty: no authentication
  TlsOptions tls;                     // --tls-cert/--tls-key/--tls-client-ca
  bool insecure_no_auth = false;      // allow no authentication beyond loopback
  std::string metrics_listen;         // HOST:PORT of /metrics (Prometheus); empty: off
  std::string advertise_address;      // where clients reach this server's sessions; empty: as they came
};

// One of a principal's uploads or loads under way (--max-uploads-per-principal).
// Raising `cancel` stops its reading within a second: its caller went away,
// or the server drains.
struct LoadSlot {
  std::atomic<bool> cancel{false};
  // Gives the slot back before the caller hears the answer (it may start the
  // next load at once); also done when the slot is dropped.
  void Release() { std::call_once(released_, release_); }

 private:
  friend class ServiceCore;
  std::once_flag released_;
  std::function<void()> release_;
};

class ServiceCore {
 public:
  explicit ServiceCore(const ServerOptions& options);  // loads the volumes; throws InputError for bad options
  ~ServiceCore();                                      // ends every session, then stops the workers

  Principal Authenticate(const grpc::CallbackServerContext& context) const {
    return authenticator_.Authenticate(context);
  }
  VolumeRegistry& volumes() { return volumes_; }
  TaskPool& loader() { return loader_; }
  // The work of calls that grows with a volume, apart from loads (which may
  // take minutes) and frames (which must not wait behind it): a new session's
  // framing over its volume and segmentation. Queues by caller, so one
  // caller's creations delay another's by one at most per thread.
  TaskPool& setup() { return setup_; }
  // Slices and picks: compute that grows with a volume and a request, apart
  // from the setup pool, so a heavy slab never delays another's CreateSession.
  TaskPool& reading() { return reading_; }
  // The compute threads one slice may use: its share of the pool, so that
  // slices at once leave half of it to the sessions' frames.
  int SliceThreads() const;
  // PACS searches: network calls, apart from loads (which may take minutes);
  // grouped by PACS, so one that stalls holds half of the slots at most.
  TaskPool& pacs_calls() { return pacs_calls_; }
  PacsDirectory& pacs() { return pacs_; }
  CallWatch& calls() { return calls_; }
  const ServerOptions& options() const { return options_; }

  // Reads the whole volume and segmentation (its framing): run it on setup().
  // It stops (Cancelled) before the framing and before the session exists
  // once `cancelled` is raised (the caller went away).
  v1::CreateSessionResponse CreateSession(const v1::CreateSessionRequest& request, const Principal& caller,
                                          const std::atomic<bool>& cancelled);
  std::shared_ptr<Session> FindSession(const std::string& id, const Principal& caller) const;
  // Shares of sessions: grants and what their holders may do (sharing.h).
  Sharing& sharing() { return sharing_; }
  void CloseSession(const std::string& id, const Principal& caller);
  // SendEvents: the batch (at most kMaxEventsPerCall) to the caller's session (Session::OnEvents).
  v1::SessionState SendEvents(const v1::SendEventsRequest& request, const Principal& caller);
  // Throws InputError past kMaxEventsPerCall events.
  void RequireBatchSize(const v1::SendEventsRequest& request) const;
  // The reading tools on the caller's session, with its current scene (runtime/reading_calls.h).
  // `cancel`: raised when the caller goes away; a slab stops early.
  v1::SliceImage RenderSlice(const v1::SliceRequest& request, const Principal& caller,
                             const std::atomic<bool>* cancel = nullptr);
  v1::PickResult Pick(const v1::PickRequest& request, const Principal& caller);
  // A rendered frame of an image of a series the caller holds (PacsService.RenderFrame): the frame's plane from
  // its PACS's metadata, sampled from the volume that series became.
  v1::SliceImage RenderFrame(const v1::RenderFrameRequest& request, const Principal& caller,
                             const std::atomic<bool>* cancel = nullptr);
  // What a still tells its caller. `done` runs once, on a worker, with the
  // image or the error; `progress` (optional) runs at once with 0 samples
  // done, then on the device's worker about twice a second while it renders.
  using SnapshotDone = std::function<void(grpc::Status, v1::SnapshotResponse)>;
  struct SnapshotCallbacks {
    SnapshotDone done;
    std::function<void(const v1::SnapshotProgress&)> progress;
  };
  // Renders a still of the session's current state on its device. It stops
  // early (CANCELLED, saying why) once `cancel` is raised: by the caller's
  // going away, or the session's end. The session does not expire meanwhile.
  void Snapshot(const v1::SnapshotRequest& request, const Principal& caller, std::shared_ptr<std::atomic<bool>> cancel,
                SnapshotCallbacks callbacks);
  // A movie of the session's view along the request's path (MovieRender), checked before its first frame: the
  // path, the frames, their cost against --max-movie-samples, and the PACS of `store_to`. Stored there after the
  // last frame, on the PACS pool; `done` runs once with the movie or the error. Its owner or presenter may.
  using MovieDone = std::function<void(grpc::Status, v1::Movie)>;
  struct MovieCallbacks {
    MovieDone done;
    std::function<void(const v1::MovieProgress&)> progress;
  };
  void RenderMovie(const v1::MovieRequest& request, const Principal& caller, std::shared_ptr<std::atomic<bool>> cancel,
                   MovieCallbacks callbacks);
  // What `caller` may see: its own sessions and uploads (an operator: all).
  v1::ServerStatus Status(const Principal& caller) const;
  // Ends sessions detached (or never attached) for longer than the options
  // allow, and the streams of grants past their expiry.
  void ExpireDetachedSessions();
  // Sets the metrics' gauges (metrics.h): sessions by state, volume memory,
  // shed connections; with `devices`, the GPUs' memory in use too.
  void PublishMetrics(bool devices) const;
  // "cuda:0 NVIDIA H100 80GB HBM3, ..." or "cpu (N threads)".
  std::string DeviceSummary() const;

  // One of `caller`'s slots for uploads and loads under way (RESOURCE_EXHAUSTED
  // past --max-uploads-per-principal), given back when dropped.
  std::shared_ptr<LoadSlot> BeginLoad(const Principal& caller);

  // SIGTERM: new sessions, loads and uploads get UNAVAILABLE, every session
  // ends with a notice, frames and stills in flight are cancelled.
  void Drain();
  bool draining() const { return draining_; }
  // Whether CreateSession would find room for one more session (readiness):
  // within --max-sessions, not draining, and on a GPU server a GPU that
  // admits a full-size 720p session (--min-session-fps).
  bool HasRoomForSession() const;
  // Throws UNAVAILABLE while draining.
  void RequireServing() const;

 private:
  bool HasRoomLocked() const;  // mu_ held
  // Throws RESOURCE_EXHAUSTED unless `caller` may hold one more session; mu_ held.
  void RequireRoomLocked(const Principal& caller) const;
  // The second volume a new session's scene fuses (Scene.fusion.volume_id),
  // leased for `caller`; null where it names none.
  std::shared_ptr<VolumeLease> LeaseFused(const v1::CreateSessionRequest& request, const Principal& caller);
  // Environment maps a scene names: resolved inside the data roots.
  MapResolver ResolveMap() const;
  // The least loaded device that admits a session rendering `pixels` a frame
  // (--min-session-fps); null where none does.
  Scheduler* Admitting(std::int64_t pixels) const;
  // The same, throwing LimitExceeded (naming the flag) where none does.
  Scheduler& RequireAdmitting(std::int64_t pixels) const;
  // `done`, after the still is stored as request.store_to asks (on the PACS
  // pool). Throws at once when it cannot be: an unknown PACS, a volume that
  // did not come from one.
  SnapshotDone StoreAfter(const v1::SnapshotRequest& request, const Session& session, const Principal& caller,
                          const v1::Scene& scene, std::shared_ptr<std::atomic<bool>> cancel, SnapshotDone done);
  // The same for a movie's request.store_to: the movie's `done`, after it is stored.
  std::function<void(grpc::Status, v1::Movie, std::string)> StoreMovieAfter(const v1::MovieRequest& request,
                                                                            const Session& session,
                                                                            const Principal& caller,
                                                                            std::shared_ptr<std::atomic<bool>> cancel,
                                                                            MovieDone done);
  void Forget(const std::string& id);
  std::shared_ptr<Session> Find(const std::string& id) const;  // whoever owns it; null when none

  ServerOptions options_;
  Backend backend_ = Backend::kCpu;                       // resolved: kCpu or kCuda
  JpegEncoderKind jpeg_encoder_ = JpegEncoderKind::kCpu;  // resolved: kCpu or kNvjpeg
  Authenticator authenticator_;
  VolumeRegistry volumes_;
  TaskPool encoder_;    // on ThreadPool::Shared(), beside the CPU's loops
  ThreadPool waiting_;  // for loader_ and setup_: their tasks mostly wait, so they keep off the compute pool
  TaskPool loader_;
  TaskPool setup_;
  TaskPool reading_;
  TaskPool pacs_calls_;
  PacsDirectory pacs_;
  CallWatch calls_;
  PixelBudget pixels_;
  std::vector<std::unique_ptr<Scheduler>> schedulers_;
  Sharing sharing_;
  const Clock::time_point started_ = Clock::now();
  std::atomic<bool> draining_{false};

  mutable std::mutex mu_;
  std::map<std::string, std::shared_ptr<Session>> sessions_;
  std::map<std::string, int> loads_;  // principal -> uploads and loads under way
  std::set<LoadSlot*> load_slots_;    // every one under way: Drain cancels them
};

}  // namespace cinevol::service

// ServiceCore: devices, sessions, stills and status.
#include "service/service_core.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <thread>

#include "core/error.h"
#include "core/log_safe.h"
#include "core/parallel_for.h"
#include "core/tone_map.h"
#include "encode/hdr_images.h"
#include "encode/image_codecs.h"
#include "io/label_volume.h"
#include "io/reader_cage.h"
#include "render/prepared_volume.h"
#include "runtime/errors.h"
#include "runtime/metrics.h"
#include "runtime/reading_calls.h"
#include "runtime/render_store.h"
#include "scene/movie_path.h"
#include "scene/presets.h"
#include "service/movie_render.h"
#include "service/still_job.h"

namespace cinevol::service {
namespace {

std::string CpuName() { return fmt::format("cpu ({} threads)", DefaultThreadCount()); }

// A movie's frames refine to this many samples per pixel unless it says otherwise: near a still's quality, in a
// fraction of its time (docs/movies.md).
constexpr std::uint32_t kDefaultMovieSpp = 64;

// A JPEG still (a DICOMweb rendered resource asks for one): near the PNG, a fraction of its bytes.
constexpr int kStillJpegQuality = 95;

v1::SnapshotResponse EncodeStill(const StillRadiance& still, v1::ImageFormat format) {
  std::vector<std::uint8_t> bytes;
  if (format == v1::EXR) {
    bytes = EncodeExr(still.image);
  } else if (format == v1::JPEG) {
    bytes = EncodeJpeg(ToneMap(still.image, still.exposure), kStillJpegQuality, ChromaSubsampling::k444);
  } else {
    bytes = EncodePng(ToneMap(still.image, still.exposure));
  }
  v1::SnapshotResponse response;
  response.set_image(bytes.data(), bytes.size());
  response.set_format(format == v1::EXR || format == v1::JPEG ? format : v1::PNG);
  response.set_width(still.image.width);
  response.set_height(still.image.height);
  response.set_spp(still.spp);
  response.set_render_us(still.render_us);
  return response;
}

}  // namespace

// Tasks at once in the pools on `waiting_` (loads and PACS calls mostly wait on a peer or a reader).
constexpr int kLoaders = 4, kSetups = 2, kReaders = 2, kPacsCalls = 4;

ServiceCore::ServiceCore(const ServerOptions& options)
    : options_(options),
      authenticator_(options.auth_tokens.empty() ? Authenticator() : Authenticator(options.auth_tokens)),
      volumes_(options.data_roots, options.volume_limits),
      encoder_("encoder", ThreadPool::Shared(),
               options.encode_threads > 0 ? options.encode_threads : ThreadPool::Shared().workers()),
      // Each pool keeps a slot free of any one caller (and of any one PACS).
      waiting_(kLoaders + kSetups + kReaders + kPacsCalls),
      loader_("loader", waiting_, {.max_running = kLoaders, .max_running_per_queue = 2, .max_running_per_group = 2}),
      setup_("setup", waiting_, {.max_running = kSetups, .max_running_per_queue = 1}),
      reading_("reading", waiting_, {.max_running = kReaders, .max_running_per_queue = 1}),
      pacs_calls_("pacs", waiting_,
                  {.max_running = kPacsCalls, .max_running_per_queue = 1, .max_running_per_group = 2}),
      pacs_(options.pacs, options.pacs_credentials),
      pixels_(options.max_total_pixels),
      sharing_(
          authenticator_, options.max_grants_per_principal, [this](const std::string& id) { return Find(id); },
          [this](const std::string& id, const Principal& caller) { return FindSession(id, caller); }) {
  const bool forwards = std::any_of(options.pacs.begin(), options.pacs.end(), [](const pacs::PacsConfig& c) {
    return c.credentials.kind == pacs::PacsCredentials::Kind::kForward;
  });
  if (forwards) authenticator_.ForwardBearerTokens();
  // Every file is read through cinevol-reader: find it now, not at the first load.
  spdlog::info("reader: {}", reader_cage::ReaderPath().string());
  if (!reader_cage::KernelHasLandlock()) {
    spdlog::warn(
        "reader: this kernel has no Landlock: readers are walled in by seccomp and rlimits only, and "
        "could open any file this server's user may read (docs/security.md#the-reader-cage)");
  }
  reader_cage::ObserveOutcomes([](std::string_view outcome) { ServerMetrics().ReaderEnded(outcome); });
  reader_cage::KeepSpareReader();
  std::string why;
  const bool cuda = CudaAvailable(&why);
  if (options.backend == Backend::kCuda && !cuda) throw InputError("--backend cuda: no usable GPU: " + why);
  backend_ = options.backend == Backend::kCpu || !cuda ? Backend::kCpu : Backend::kCuda;
  if (backend_ == Backend::kCuda) {
    const std::vector<GpuInfo> gpus = ListGpus();
    for (const GpuInfo& gpu : gpus) {
      const bool wanted = options.devices.empty() ||
                          std::find(options.devices.begin(), options.devices.end(), gpu.index) != options.devices.end();
      if (!wanted) continue;
      SetGpuWait(gpu.index, options.gpu_wait);  // before its workers start
      schedulers_.push_back(std::make_unique<Scheduler>(fmt::format("cuda:{} {}", gpu.index, gpu.name), gpu.index,
                                                        options.workers_per_gpu, options.pixels_in_flight_per_gpu));
    }
    for (int d : options.devices) {
      if (std::none_of(gpus.begin(), gpus.end(), [d](const GpuInfo& g) { return g.index == d; })) {
        throw InputError(fmt::format("--devices: GPU {} is not a usable GPU ({} found)", d, gpus.size()));
      }
    }
  } else {
    if (!options.devices.empty()) throw InputError("--devices: names GPUs, but the backend is the CPU");
    schedulers_.push_back(std::make_unique<Scheduler>(CpuName(), std::nullopt, 1));
  }
  jpeg_encoder_ = ChooseJpegEncoder(options.jpeg_encoder, backend_);
  const std::vector<std::string> preload =
      options.volumes.empty() ? std::vector<std::string>{"phantom:head"} : options.volumes;
  for (const std::string& spec : preload) volumes_.AddFromSpec(spec);
}

ServiceCore::~ServiceCore() {
  pacs_calls_.Stop();  // its searches use pacs_
  setup_.Stop();       // first: what it creates is ended below
  reading_.Stop();
  std::vector<std::shared_ptr<Session>> open;
  {
    std::lock_guard lock(mu_);
    for (auto& [id, s] : sessions_) open.push_back(s);
  }
  for (auto& s : open) s->End(RpcError::Unavailable("the server is shutting down").status());
  open.clear();
  // Workers first (encoders wake them), then the pools (their tasks hold sessions).
  for (auto& s : schedulers_) s->Stop();
  encoder_.Stop();
  loader_.Stop();
}

std::string ServiceCore::DeviceSummary() const {
  std::vector<std::string> names;
  for (const auto& s : schedulers_) names.push_back(s->name());
  return fmt::format("{}", fmt::join(names, ", "));
}

Scheduler* ServiceCore::Admitting(std::int64_t pixels) const {
  const double min_fps = backend_ == Backend::kCuda ? options_.min_session_fps : 0.0;
  Scheduler* best = nullptr;
  for (const auto& s : schedulers_) {
    if (s->Admits(pixels, min_fps) && (!best || s->sessions < best->sessions)) best = s.get();
  }
  return best;
}

Scheduler& ServiceCore::RequireAdmitting(std::int64_t pixels) const {
  if (Scheduler* scheduler = Admitting(pixels)) return *scheduler;
  const Scheduler& first = *schedulers_.front();
  throw LimitExceeded("min-session-fps",
                      fmt::format("every GPU is at capacity: another session of {} pixels a frame would take the "
                                  "sessions there under {} frames a second ({} rendered {:.0f} Mpixels a second "
                                  "while busy; --min-session-fps)",
                                  pixels, options_.min_session_fps, first.name(), first.saturated_pixel_rate() / 1e6));
}

namespace {

// The pixels a new session's frames render for admission: its viewport, at
// the smallest interactive scale where it has an interactive budget (under
// load it steps down to that).
std::int64_t AdmissionPixels(const v1::SessionState& state, Backend backend) {
  const std::int64_t viewport = std::int64_t(state.viewport().width()) * state.viewport().height();
  if (SessionFrameSettings(backend, state.stream()).interactive_frame_ms <= 0) return viewport;
  const float smallest = std::end(kInteractiveScales)[-1];
  return std::int64_t(double(viewport) * smallest * smallest);
}

}  // namespace

void ServiceCore::RequireServing() const {
  if (draining_) throw RpcError::Unavailable("the server is shutting down");
}

void ServiceCore::RequireRoomLocked(const Principal& caller) const {
  if (int(sessions_.size()) >= options_.max_sessions) {
    throw LimitExceeded("max-sessions", fmt::format("this server holds its maximum of {} sessions (--max-sessions)",
                                                    options_.max_sessions));
  }
  const auto own = std::count_if(sessions_.begin(), sessions_.end(),
                                 [&](const auto& entry) { return entry.second->owner() == caller.name; });
  if (own >= options_.max_sessions_per_principal) {
    throw LimitExceeded(
        "max-sessions-per-principal",
        fmt::format("you hold {} sessions, this server's limit per user (--max-sessions-per-principal): "
                    "close one first",
                    own));
  }
}

MapResolver ServiceCore::ResolveMap() const {
  return [this](const std::string& map, const std::string& field) {
    return volumes_.ResolveDataPath(map, field).string();  // environment maps: only inside the data roots
  };
}

std::shared_ptr<VolumeLease> ServiceCore::LeaseFused(const v1::CreateSessionRequest& request, const Principal& caller) {
  const std::string& id = request.scene().fusion().volume_id();
  if (request.initial_case() != v1::CreateSessionRequest::kScene || id.empty()) return nullptr;
  std::shared_ptr<VolumeLease> fused = volumes_.Lease(id, caller);
  if (fused->phases() > 1) {
    throw InputError(
        fmt::format("scene.fusion.volume_id: volume '{}' is a time series of {} phases; a second volume "
                    "has one",
                    id, fused->phases()));
  }
  return fused;
}

v1::CreateSessionResponse ServiceCore::CreateSession(const v1::CreateSessionRequest& request, const Principal& caller,
                                                     const std::atomic<bool>& cancelled) {
  RequireServing();
  std::shared_ptr<VolumeLease> volume = volumes_.Lease(request.volume_id(), caller);
  std::shared_ptr<VolumeLease> fused = LeaseFused(request, caller);
  {
    std::lock_guard lock(mu_);
    RequireRoomLocked(caller);  // before the framing: a refusal costs no scan
  }
  auto require_caller = [&] {
    if (cancelled) throw Cancelled("CreateSession: the caller went away; no session was created");
  };
  // Resolving frames a named view over the volume's blocks and, with a
  // segmentation, every label voxel: seconds for 512^3.
  const SceneContext scene_context{*volume->volume(),
                                   volume->labels().get(),
                                   volume->id(),
                                   ResolveMap(),
                                   volume->phases(),
                                   fused ? fused->volume().get() : nullptr,
                                   fused ? fused->id() : std::string()};
  v1::SessionState state = InitialState(request, scene_context, options_.limits);
  const v1::Scene& scene = state.scene();
  *state.mutable_stream() = ToStreamSettings(SessionFrameSettings(backend_, state.stream()));
  require_caller();
  Scheduler& scheduler = RequireAdmitting(AdmissionPixels(state, backend_));
  // The volume reaches the device here, not inside the first frame on a
  // worker that other sessions share.
  std::vector<std::shared_ptr<const VolumeCopy>> prepared =
      PrepareOnDevice(*volume, fused.get(), scheduler, options_.limits.max_phase_copy_bytes);
  require_caller();
  SessionContext context{&scheduler,
                         &encoder_,
                         backend_,
                         jpeg_encoder_,
                         &options_.limits,
                         ResolveMap(),
                         &pixels_,
                         [this](const std::string& id) { Forget(id); },
                         &setup_};
  std::shared_ptr<Session> session;
  {
    std::lock_guard lock(mu_);
    RequireServing();  // Drain() raises the flag, then ends what it finds here under mu_
    RequireRoomLocked(caller);
    // 128 random bits: ids are not secrets (ownership is checked on every call), nor guessable.
    const std::string id = RandomHex(16);
    session = std::make_shared<Session>(id, caller.name, std::move(volume), std::move(fused), state, std::move(context),
                                        std::move(prepared));
    sessions_[id] = session;
  }
  spdlog::info("session {}: created for {} on {}, volume {}, {}x{}", session->id(), LogSafe(caller.name),
               scheduler.name(), LogSafe(request.volume_id()), scene.render().width(), scene.render().height());
  v1::CreateSessionResponse response;
  response.set_session_id(session->id());
  *response.mutable_scene() = scene;
  response.set_device(scheduler.name());
  response.set_address(options_.advertise_address);
  return response;
}

std::shared_ptr<Session> ServiceCore::Find(const std::string& id) const {
  std::lock_guard lock(mu_);
  auto it = sessions_.find(id);
  return it == sessions_.end() ? nullptr : it->second;
}

std::shared_ptr<Session> ServiceCore::FindSession(const std::string& id, const Principal& caller) const {
  std::shared_ptr<Session> session = Find(id);
  if (!session) throw RpcError::NotFound(fmt::format("session_id: no session '{}'", id));
  if (!caller.is_operator) RequireOwner(caller, session->owner(), fmt::format("session '{}'", id));
  return session;
}

void ServiceCore::CloseSession(const std::string& id, const Principal& caller) {
  FindSession(id, caller)->End(OkStatus("session closed"));
}

void ServiceCore::RequireBatchSize(const v1::SendEventsRequest& request) const {
  if (request.events_size() > kMaxEventsPerCall) {
    throw InputError(fmt::format("events: {} events; at most {} a call", request.events_size(), kMaxEventsPerCall));
  }
}

v1::SessionState ServiceCore::SendEvents(const v1::SendEventsRequest& request, const Principal& caller) {
  RequireBatchSize(request);
  return FindSession(request.session_id(), caller)->OnEvents(request.events(), Clock::now());
}

namespace {

// What the reading tools read of a session: its scene now (a time series at the phase it shows) and its volumes.
struct SessionReading {
  v1::Scene scene;
  std::shared_ptr<VolumeLease> volume, fused;
};
SessionReading ReadingOf(const Session& session) {
  SessionReading reading{{}, session.volume(), session.fused()};
  FrameSettings settings;
  session.CurrentScene(reading.scene, settings);
  return reading;
}

}  // namespace

int ServiceCore::SliceThreads() const {
  return std::max(1, ThreadPool::Shared().workers() / (2 * reading_.max_running()));
}

v1::SliceImage ServiceCore::RenderSlice(const v1::SliceRequest& request, const Principal& caller,
                                        const std::atomic<bool>* cancel) {
  const SessionReading r = ReadingOf(*FindSession(request.session_id(), caller));
  return SliceOf(request, r.scene, *r.volume, r.fused.get(), cancel, SliceThreads());
}

v1::PickResult ServiceCore::Pick(const v1::PickRequest& request, const Principal& caller) {
  const SessionReading r = ReadingOf(*FindSession(request.session_id(), caller));
  return PickOn(request, r.scene, *r.volume, r.fused.get());
}

v1::SliceImage ServiceCore::RenderFrame(const v1::RenderFrameRequest& request, const Principal& caller,
                                        const std::atomic<bool>* cancel) {
  pacs::CheckUid(request.study_uid(), "study_uid");
  pacs::CheckUid(request.series_uid(), "series_uid");
  const auto pacs = pacs_.Find(request.pacs(), caller, "pacs");
  // The series as LoadSeries makes it with no choices: its volume's grid is the one the PACS's metadata places.
  const std::optional<v1::VolumeInfo> held =
      volumes_.FindHeld(PacsSource({request.pacs(), request.study_uid(), request.series_uid()}, ""), caller);
  if (!held) {
    throw RpcError::FailedPrecondition(
        fmt::format("series {} of PACS '{}' is not loaded by this caller: LoadSeries "
                    "it first (with no orientation or resampling)",
                    request.series_uid(), request.pacs()));
  }
  const std::shared_ptr<VolumeLease> volume = volumes_.Lease(held->id(), caller);
  const int frame = int(std::min<std::uint32_t>(request.frame(), 1u << 30));
  const pacs::FramePlane plane = pacs::FetchFramePlane(*pacs, request.study_uid(), request.series_uid(),
                                                       request.sop_instance_uid(), frame, cancel);
  return FrameOf(request, plane, *volume->volume(), cancel, SliceThreads());
}

std::shared_ptr<LoadSlot> ServiceCore::BeginLoad(const Principal& caller) {
  RequireServing();
  std::lock_guard lock(mu_);
  int& count = loads_[caller.name];
  if (count >= options_.max_uploads_per_principal) {
    throw LimitExceeded("max-uploads-per-principal",
                        fmt::format("you have {} uploads or loads under way, this server's limit "
                                    "(--max-uploads-per-principal)",
                                    count));
  }
  ++count;
  auto* slot = new LoadSlot;
  slot->release_ = [this, name = caller.name] {
    std::lock_guard lock(mu_);
    if (--loads_[name] == 0) loads_.erase(name);
  };
  load_slots_.insert(slot);
  return std::shared_ptr<LoadSlot>(slot, [this](LoadSlot* done) {
    done->Release();
    {
      std::lock_guard lock(mu_);
      load_slots_.erase(done);
    }
    delete done;
  });
}

void ServiceCore::Drain() {
  if (draining_.exchange(true)) return;
  std::vector<std::shared_ptr<Session>> open;
  {
    std::lock_guard lock(mu_);
    for (auto& [id, s] : sessions_) open.push_back(s);
    for (LoadSlot* slot : load_slots_) slot->cancel = true;  // their readers are killed
  }
  spdlog::info("draining: {} session(s) end now", open.size());
  for (auto& s : open) s->Drain();
}

bool ServiceCore::HasRoomForSession() const {
  std::lock_guard lock(mu_);
  return HasRoomLocked();
}

bool ServiceCore::HasRoomLocked() const {
  constexpr std::int64_t kReadinessPixels = 1280 * 720;  // the session readiness vouches for
  return !draining_ && int(sessions_.size()) < options_.max_sessions && Admitting(kReadinessPixels) != nullptr;
}

void ServiceCore::Forget(const std::string& id) {
  sharing_.SessionEnded(id);
  std::shared_ptr<Session> last;  // may be the last reference: released outside the lock
  std::lock_guard lock(mu_);
  auto it = sessions_.find(id);
  if (it == sessions_.end()) return;
  last = std::move(it->second);
  sessions_.erase(it);
}

void ServiceCore::Snapshot(const v1::SnapshotRequest& request, const Principal& caller,
                           std::shared_ptr<std::atomic<bool>> cancel, SnapshotCallbacks callbacks) {
  RequireServing();
  std::shared_ptr<Session> session = FindSession(request.session_id(), caller);
  v1::Scene scene;
  FrameSettings settings;
  session->CurrentScene(scene, settings);
  const std::uint64_t pixels = std::uint64_t(scene.render().width()) * scene.render().height();
  const int spp = SnapshotSpp(request, pixels, options_.limits);
  // A step's samples stay within one streamed frame's budget, so other
  // sessions' frames interleave and a cancel is seen soon.
  const int max_chunk =
      int(std::clamp<std::uint64_t>(options_.limits.max_frame_samples / std::max<std::uint64_t>(pixels, 1), 1, 8));
  if (callbacks.progress) {  // at once: the client knows the still is under way before its first sample
    v1::SnapshotProgress accepted;
    accepted.set_spp(std::uint32_t(spp));
    callbacks.progress(accepted);
  }
  if (!request.store_to().empty()) {
    callbacks.done = StoreAfter(request, *session, caller, scene, cancel, std::move(callbacks.done));
  }
  // The session does not expire while its still renders (EndStill).
  session->BeginStill(cancel);
  StillJob::Callbacks job;
  job.done = [session, format = request.format(), encoder = &encoder_, done = std::move(callbacks.done)](
                 grpc::Status status, StillRadiance still) mutable {
    session->EndStill();
    if (!status.ok()) return done(std::move(status), {});
    encoder->Submit([still = std::move(still), format, done = std::move(done)] {
      v1::SnapshotResponse response;
      const grpc::Status encoded = Guarded([&] { response = EncodeStill(still, format); });
      done(encoded, std::move(response));
    });
  };
  job.progress = std::move(callbacks.progress);
  job.why_cancelled = [session] {
    const std::string why = session->EndReason();
    return why.empty() ? std::string("its caller went away")
                       : fmt::format("its session '{}' ended: {}", session->id(), why);
  };
  session->scheduler()->Wake(std::make_shared<StillJob>(session->volume(), session->fused(), std::move(scene), spp,
                                                        max_chunk, backend_, std::move(cancel), std::move(job)));
}

void ServiceCore::RenderMovie(const v1::MovieRequest& request, const Principal& caller,
                              std::shared_ptr<std::atomic<bool>> cancel, MovieCallbacks callbacks) {
  RequireServing();
  const std::shared_ptr<Session> session = sharing_.OwnedOrPresented(request.session_id(), caller);
  MovieRender::Plan plan;
  plan.request = request;
  plan.frames = MovieFrames(request);
  FrameSettings settings;
  session->CurrentScene(plan.start, settings);
  MovieFrame(plan.start, request, MovieVolumeOf(*session->volume()), 0,
             plan.frames);  // throws for a path it cannot take
  const std::uint64_t pixels = std::uint64_t(plan.start.render().width()) * plan.start.render().height();
  v1::SnapshotRequest still;
  still.set_spp(request.has_spp() ? request.spp() : kDefaultMovieSpp);
  plan.spp = SnapshotSpp(still, pixels, options_.limits);
  plan.max_chunk_spp =
      int(std::clamp<std::uint64_t>(options_.limits.max_frame_samples / std::max<std::uint64_t>(pixels, 1), 1, 8));
  const std::uint64_t samples = std::uint64_t(plan.frames) * std::uint64_t(plan.spp) * pixels;
  if (samples > options_.limits.max_movie_samples) {
    throw OverLimit("max-movie-samples",
                    fmt::format("{} frames of {} spp at {} pixels are {} samples, over this server's limit of {} "
                                "(--max-movie-samples)",
                                plan.frames, plan.spp, pixels, samples, options_.limits.max_movie_samples));
  }
  if (request.has_crf() && request.crf() > 51) {
    throw InputError(fmt::format("crf: {} is outside [0, 51]", request.crf()));
  }
  plan.crf = request.has_crf() ? int(request.crf()) : 18;
  MovieRender::Callbacks movie;
  movie.progress = std::move(callbacks.progress);
  if (request.store_to().empty()) {
    movie.done = [done = std::move(callbacks.done)](grpc::Status status, v1::Movie answer, std::string) {
      done(std::move(status), std::move(answer));
    };
  } else {
    movie.done = StoreMovieAfter(request, *session, caller, cancel, std::move(callbacks.done));
  }
  MovieRender::Start(session, std::move(plan), backend_, encoder_, std::move(cancel), std::move(movie));
}

std::function<void(grpc::Status, v1::Movie, std::string)> ServiceCore::StoreMovieAfter(
    const v1::MovieRequest& request, const Session& session, const Principal& caller,
    std::shared_ptr<std::atomic<bool>> cancel, MovieDone done) {
  const auto to = pacs_.Find(request.store_to(), caller, "store_to");
  Principal owner;  // the volume is the owner's, whoever presents
  owner.name = session.owner();
  const v1::VolumeInfo volume = volumes_.Describe(session.volume()->id(), owner);
  const PacsOrigin origin =
      OriginOf(volume, "a movie goes back into the study of a series loaded with LoadSeries", "store_to: ");
  const auto from = pacs_.Find(origin.pacs, caller, "store_to");
  const std::string description = request.path_case() == v1::MovieRequest::kOrbitDegrees
                                      ? fmt::format("orbit {:g} deg", request.orbit_degrees())
                                      : "sweep " + v1::SliceAxis_Name(request.sweep());
  auto finish = std::make_shared<MovieDone>(std::move(done));  // called once, whoever runs it
  return [this, to, from, origin, description, cancel, finish, queue = caller.name, group = request.store_to()](
             grpc::Status status, v1::Movie movie, std::string h264) {
    if (!status.ok()) return (*finish)(std::move(status), {});
    auto stream = std::make_shared<pacs::MovieStream>();
    stream->width = int(movie.width());
    stream->height = int(movie.height());
    stream->fps = int(movie.fps());
    stream->frames = int(movie.frames());
    stream->h264 = std::move(h264);
    stream->description = description;
    const bool queued = pacs_calls_.Submit(
        [=, movie = std::move(movie)]() mutable {
          const grpc::Status stored = Guarded([&] {
            *movie.mutable_stored() = StoreMovie(*to, *from, origin, *stream, CINEVOL_VERSION, cancel.get());
          });
          (*finish)(stored, stored.ok() ? std::move(movie) : v1::Movie());
        },
        queue, group);
    if (!queued) (*finish)(RpcError::Unavailable("the server is shutting down; the movie was not stored").status(), {});
  };
}

ServiceCore::SnapshotDone ServiceCore::StoreAfter(const v1::SnapshotRequest& request, const Session& session,
                                                  const Principal& caller, const v1::Scene& scene,
                                                  std::shared_ptr<std::atomic<bool>> cancel, SnapshotDone done) {
  // Checked before a sample is rendered: the PACS named, the volume's own PACS and study.
  const auto to = pacs_.Find(request.store_to(), caller, "store_to");
  if (request.format() == v1::EXR || request.format() == v1::JPEG) {
    throw InputError("store_to: a render goes to a PACS as PNG; leave format unset");
  }
  const v1::VolumeInfo volume = volumes_.Describe(session.volume()->id(), caller);
  const PacsOrigin origin =
      OriginOf(volume, "a render goes back into the study of a series loaded with LoadSeries", "store_to: ");
  const auto from = pacs_.Find(origin.pacs, caller, "store_to");
  auto finish = std::make_shared<SnapshotDone>(std::move(done));  // called once, whoever runs it
  std::shared_ptr<const Volume> volume_held = session.volume()->volume();
  const std::string labels_source = volume.has_labels() ? volume.labels().source() : std::string();
  return [this, to, from, origin, scene, volume_held, labels_source, cancel, finish](grpc::Status status,
                                                                                     v1::SnapshotResponse still) {
    if (!status.ok()) return (*finish)(std::move(status), std::move(still));
    const bool queued = pacs_calls_.Submit([=, still = std::move(still)]() mutable {
      const grpc::Status stored = Guarded([&] {
        StoreRender(*to, *from, origin, still, scene, *volume_held, labels_source, CINEVOL_VERSION, cancel.get());
      });
      (*finish)(stored, stored.ok() ? std::move(still) : v1::SnapshotResponse());
    });
    if (!queued) (*finish)(RpcError::Unavailable("the server is shutting down; the still was not stored").status(), {});
  };
}

void ServiceCore::ExpireDetachedSessions() {
  sharing_.ExpireGrants();
  const Clock::time_point now = Clock::now();
  const auto detached = Seconds(options_.detached_session_seconds);
  const auto unattached = Seconds(options_.unattached_session_seconds);
  std::vector<std::shared_ptr<Session>> expired;
  {
    std::lock_guard lock(mu_);
    for (auto& [id, s] : sessions_) {
      if (s->Expired(now, detached, unattached)) expired.push_back(s);
    }
  }
  for (auto& s : expired) {
    s->End(RpcError::DeadlineExceeded(
               "no stream attached in time (--detached-session-seconds, --unattached-session-seconds)")
               .status());
  }
}

void ServiceCore::PublishMetrics(bool devices) const {
  std::vector<std::shared_ptr<Session>> sessions;
  {
    std::lock_guard lock(mu_);
    for (const auto& [id, s] : sessions_) sessions.push_back(s);
  }
  SessionStates states;
  for (const auto& s : sessions) {
    switch (s->Status().state()) {
      case v1::SessionStatus::STARTING:
        ++states.starting;
        break;
      case v1::SessionStatus::PAUSED:
        ++states.paused;
        break;
      case v1::SessionStatus::IDLE:
        ++states.idle;
        break;
      case v1::SessionStatus::DETACHED:
        ++states.detached;
        break;
      default:
        ++states.rendering;
        break;
    }
  }
  Metrics& metrics = ServerMetrics();
  metrics.SetSessions(states);
  std::uint64_t volume_bytes = 0;
  for (const v1::VolumeInfo& v : volumes_.List(Principal{"", true})) volume_bytes += v.memory_bytes();
  metrics.SetVolumeMemory(volume_bytes);
  metrics.SetConnectionsShed(ShedConnections());
  if (devices && backend_ == Backend::kCuda) {
    for (const GpuInfo& g : ListGpus()) {
      for (const auto& s : schedulers_) {
        if (s->gpu() && *s->gpu() == g.index) metrics.SetDeviceMemoryUsed(g.index, g.total_bytes - g.free_bytes);
      }
    }
  }
}

v1::ServerStatus ServiceCore::Status(const Principal& caller) const {
  v1::ServerStatus status;
  status.set_version(CINEVOL_VERSION);
  status.set_uptime_seconds(std::chrono::duration<double>(Clock::now() - started_).count());
  const std::vector<GpuInfo> gpus = backend_ == Backend::kCuda ? ListGpus() : std::vector<GpuInfo>{};
  const std::vector<VolumeCopyStatus> copies = VolumeCache::Get().Copies();
  for (const auto& s : schedulers_) {
    v1::DeviceStatus* d = status.add_devices();
    d->set_name(s->name());
    d->set_sessions(s->sessions);
    d->set_frames_rendered(s->frames_rendered);
    d->set_busy_seconds(s->busy_seconds());
    for (const VolumeCopyStatus& c : copies) {
      if (c.device != s->gpu().value_or(kHostDevice)) continue;
      d->set_volume_copies(d->volume_copies() + 1);
      d->set_volume_copy_bytes(d->volume_copy_bytes() + c.bytes);
    }
    for (const GpuInfo& g : gpus) {
      if (s->gpu() && g.index == *s->gpu()) {
        d->set_memory_total_bytes(g.total_bytes);
        d->set_memory_free_bytes(g.free_bytes);
      }
    }
  }
  std::vector<std::shared_ptr<Session>> sessions;
  {
    std::lock_guard lock(mu_);
    for (const auto& [id, s] : sessions_) {
      if (caller.is_operator || s->owner() == caller.name) sessions.push_back(s);
    }
    status.set_sessions_held(std::uint32_t(sessions_.size()));
    status.set_accepting_sessions(HasRoomLocked());
  }
  status.set_max_sessions(std::uint32_t(options_.max_sessions));
  for (const std::string& name : PresetNames()) status.add_presets(name);
  for (const auto& s : sessions) *status.add_sessions() = s->Status();
  for (v1::VolumeInfo& v : volumes_.List(caller)) *status.add_volumes() = std::move(v);
  status.set_encode_threads(encoder_.max_running());
  status.set_encode_queue(encoder_.queued());
  return status;
}

}  // namespace cinevol::service

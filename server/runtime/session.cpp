// Session: event merging, the render gate, and the frame's way from the
// scheduler through the encoder to the stream.
#include "runtime/session.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <utility>

#include "core/log_safe.h"
#include "io/label_volume.h"
#include "runtime/errors.h"
#include "runtime/metrics.h"
#include "scene/presets.h"
#include "scene/scene_file.h"
#include "scene/time_series.h"

namespace cinevol::service {
namespace {

// Frames may be encoding while the next renders; more would only be dropped.
constexpr int kMaxEncodesInFlight = 2;
// A 720p frame in 4 bands encodes in half the time (2.32 -> 1.09 ms on the
// H100 host); more bands add thread starts and restart markers for little
// (docs/performance.md).
constexpr int kMaxJpegBands = 4;

}  // namespace

// What one step renders, taken under the lock.
struct Session::Work {
  bool update = false;   // scene and settings changed since the pipeline saw them
  unsigned changes = 0;  // SceneChange bits: what the events changed
  int phase = 0;         // of a time series, to show
  v1::Scene scene;
  FrameSettings settings;
  FrameStamp stamp;
};

void PixelBudget::Exchange(std::uint64_t release, std::uint64_t take) {
  std::lock_guard lock(mu_);
  const std::uint64_t next = used_ - std::min(release, used_) + take;
  if (take > release && next > limit_) {
    throw LimitExceeded("max-total-pixels",
                        fmt::format("viewport: {} pixels more would pass this server's limit of {} pixels for "
                                    "all sessions together (--max-total-pixels; {} in use)",
                                    take - release, limit_, used_));
  }
  used_ = next;
}

std::uint64_t PixelBudget::used() const {
  std::lock_guard lock(mu_);
  return used_;
}

std::vector<std::shared_ptr<const VolumeCopy>> PrepareOnDevice(const VolumeLease& volume, const VolumeLease* fused,
                                                               const Scheduler& scheduler, std::uint64_t phase_budget) {
  const int device = scheduler.gpu().value_or(kHostDevice);
  std::vector<std::shared_ptr<const VolumeCopy>> copies;
  const int window = PhaseCopies::Window(volume, device, phase_budget);
  for (int k = 0; k < window; ++k) {
    copies.push_back(CopyOf(volume.phase(k), device));
  }
  if (fused) {  // as the renderer's SetFusion asks for it
    copies.push_back(
        VolumeCache::Get().Acquire(fused->volume(), kAutoBrickSize, device, kSessionRenderer.volume_texture));
  }
  return copies;
}

Session::Session(std::string id, std::string owner, std::shared_ptr<VolumeLease> volume,
                 std::shared_ptr<VolumeLease> fused, v1::SessionState state, SessionContext context,
                 std::vector<std::shared_ptr<const VolumeCopy>> prepared)
    : id_(std::move(id)),
      owner_(std::move(owner)),
      volume_(std::move(volume)),
      fused_(std::move(fused)),
      context_(std::move(context)),
      scene_context_{*volume_->volume(),
                     volume_->labels().get(),
                     volume_->id(),
                     context_.resolve_map,
                     volume_->phases(),
                     fused_ ? fused_->volume().get() : nullptr,
                     fused_ ? fused_->id() : std::string()},
      current_(std::move(state)),
      settings_(SessionFrameSettings(context_.backend, current_.stream())),
      since_(Clock::now()),
      pixels_(std::uint64_t(current_.viewport().width()) * current_.viewport().height()),
      events_(context_.limits->max_events_per_second, since_),
      batched_(kReadPacing * context_.limits->max_events_per_second, since_),
      prepared_(std::move(prepared)) {
  context_.pixels->Exchange(0, pixels_);
  SetStepPixelsLocked(pixels_, render_scale_);
  current_.set_presenter(owner_);  // until a grant presents (docs/sharing.md)
  ++context_.scheduler->sessions;
}

Session::~Session() {
  --context_.scheduler->sessions;
  context_.scheduler->AddSessionPixels(-step_pixels_.load());
  context_.pixels->Exchange(pixels_, 0);
}

void Session::Attach(FrameStream* stream) {
  {
    std::lock_guard lock(mu_);
    if (state_ == State::kEnded) {
      throw RpcError::NotFound(fmt::format("session '{}' has ended", id_));
    }
    if (stream_) {
      sent_before_ += stream_->frames_sent();
      dropped_before_ += stream_->frames_dropped();
      stream_->End(RpcError::Aborted(fmt::format("another stream attached to session '{}'", id_)).status());
    }
    stream_ = stream;
    state_ = State::kRendering;
    cancel_ = false;
    last_event_seq_ = last_owner_seq_ = 0;  // sequence numbers count per stream
    current_.set_last_event_seq(0);
    current_.set_paused(false);  // an attach resumes
    event_unrendered_ = false;
    dirty_ = true;  // a fresh pipeline (or the old one) takes the scene again
    state_unsent_ = true;
    stream_->SendNotice(v1::Notice::INFO,
                        fmt::format("attached to session '{}' on {}", id_, context_.scheduler->name()));
    NoteMisfitLocked();
  }
  Wake();
}

void Session::AttachWatcher(FrameStream* stream, const std::string& grant_id, const std::string& holder) {
  AddWatcher(stream, grant_id, holder);
  Wake();
}

void Session::AddWatcher(FrameStream* stream, const std::string& grant_id, const std::string& holder) {
  std::lock_guard lock(mu_);
  if (state_ == State::kEnded) throw RpcError::NotFound(fmt::format("session '{}' has ended", id_));
  if (int(watchers_.size()) >= context_.limits->max_viewers_per_session) {
    throw LimitExceeded("max-viewers-per-session",
                        fmt::format("session '{}' has {} viewers, this server's limit (--max-viewers-per-session)", id_,
                                    watchers_.size()));
  }
  const auto by_grant =
      std::count_if(watchers_.begin(), watchers_.end(), [&](const Watcher& w) { return w.grant_id == grant_id; });
  if (by_grant >= context_.limits->max_viewers_per_grant) {
    throw LimitExceeded("max-viewers-per-grant",
                        fmt::format("this share of session '{}' has {} viewers, this server's limit for one share "
                                    "(--max-viewers-per-grant); ask the owner for a share of your own",
                                    id_, by_grant));
  }
  watchers_.push_back({stream, grant_id, holder});
  current_.set_viewers(std::uint32_t(watchers_.size()));
  stream->SendNotice(v1::Notice::INFO, fmt::format("watching session '{}' on {}", id_, context_.scheduler->name()));
  SendStateLocked();  // everyone learns the count; the newcomer the scene
  if (newest_frame_) {
    stream->OfferFrame(*newest_frame_, Clock::now());
  } else if (stream_ && state_ == State::kIdle) {
    state_ = State::kRendering;  // the first watcher: one more frame shows it the view
  }
}

int Session::EndWatchers(const std::string& grant_id, const grpc::Status& status) {
  std::lock_guard lock(mu_);
  int ended = 0;
  for (const Watcher& w : watchers_) {
    if (w.grant_id != grant_id) continue;
    w.stream->End(status);  // its OnDone detaches it
    ++ended;
  }
  return ended;
}

int Session::Watching(const std::string& grant_id) const {
  std::lock_guard lock(mu_);
  return int(
      std::count_if(watchers_.begin(), watchers_.end(), [&](const Watcher& w) { return w.grant_id == grant_id; }));
}

void Session::SetPresenter(const std::string& who) {
  std::lock_guard lock(mu_);
  current_.set_presenter(who);
  SendStateLocked();
}

void Session::OnPointer(const std::string& who, const v1::Pointer& pointer, Clock::time_point arrival) {
  std::lock_guard lock(mu_);
  PointLocked(who, pointer, arrival);
}

void Session::PointLocked(const std::string& who, const v1::Pointer& pointer, Clock::time_point arrival) {
  TokenBucket& rate = pointer_rates_.try_emplace(who, kPointerRate, arrival).first->second;
  if (!rate.Take(arrival)) return;  // a pointer moves on: the next move shows it
  if (ApplyPointer(current_, who, pointer)) SendStateLocked();
}

void Session::Detach(FrameStream* stream) {
  {
    std::lock_guard lock(mu_);
    const auto watcher =
        std::find_if(watchers_.begin(), watchers_.end(), [&](const Watcher& w) { return w.stream == stream; });
    if (watcher != watchers_.end()) {  // a watcher leaves; the session goes on as it was
      const std::string holder = watcher->holder;
      watchers_.erase(watcher);
      const bool still_watching =
          std::any_of(watchers_.begin(), watchers_.end(), [&](const Watcher& w) { return w.holder == holder; });
      if (!still_watching) {  // its pointer goes with it
        pointer_rates_.erase(holder);
        HidePointer(current_, holder);
      }
      current_.set_viewers(std::uint32_t(watchers_.size()));
      SendStateLocked();
      return;
    }
    if (stream_ != stream) return;
    sent_before_ += stream_->frames_sent();
    dropped_before_ += stream_->frames_dropped();
    stream_ = nullptr;
    state_ = State::kDetached;
    since_ = Clock::now();
    cancel_ = true;  // nobody will see the frame in flight
  }
  Wake();  // the next step frees the device memory
}

void Session::OnWritable(FrameStream* stream) {
  {
    std::lock_guard lock(mu_);
    if (stream_ != stream) return;
  }
  Wake();
}

void Session::OnEvent(const v1::SessionEvent& event, Clock::time_point arrival) {
  {
    std::lock_guard lock(mu_);
    OnEventLocked(event, arrival);
  }
  Wake();
}

v1::SessionState Session::OnEvents(const google::protobuf::RepeatedPtrField<v1::SessionEvent>& events,
                                   Clock::time_point arrival, bool from_grant) {
  std::exception_ptr bad;
  v1::SessionState state;
  {
    std::lock_guard lock(mu_);
    if (state_ == State::kEnded) {
      throw RpcError::NotFound(fmt::format("session '{}' has ended", id_));
    }
    if (!batched_.Take(arrival, events.size())) {
      throw LimitExceeded(
          "max-events-per-second",
          fmt::format("events: more than {} events a second to session '{}' ({} x "
                      "--max-events-per-second); none of these {} was applied",
                      kReadPacing * context_.limits->max_events_per_second, id_, kReadPacing, events.size()));
    }
    try {
      for (const v1::SessionEvent& event : events) OnEventLocked(event, arrival, from_grant);
    } catch (...) {
      bad = std::current_exception();  // the events before it stay applied
    }
    state = current_;
  }
  Wake();
  if (bad) std::rethrow_exception(bad);
  return state;
}

v1::SessionState Session::CurrentState() const {
  std::lock_guard lock(mu_);
  return current_;
}

void Session::OnEventLocked(v1::SessionEvent event, Clock::time_point arrival, bool from_grant) {
  ServerMetrics().EventReceived();
  if (event.has_pointer()) {  // shared at once; no frame answers it
    PointLocked(owner_, event.pointer(), arrival);
    return;
  }
  if (event.has_measurements()) {  // the same: the picture does not change
    ApplyEvent(current_, event, scene_context_, context_.limits);
    SendStateLocked();
    return;
  }
  if (from_grant) {
    event.set_seq(last_event_seq_ + 1);
  } else if (event.seq() <= last_owner_seq_ && last_owner_seq_ > 0) {
    throw InputError(fmt::format("event {}: seq must increase (the last was {})", event.seq(), last_owner_seq_));
  } else {
    last_owner_seq_ = event.seq();
  }
  bool changes_picture = !event.has_pause() && !event.has_resume() && !event.has_stream();
  if (event.has_pause() || event.has_resume() || events_.Take(arrival)) {
    ApplyCoalescedLocked();  // what came earlier applies first
    if (ApplyLocked(event, arrival) == 0) changes_picture = false;
  } else {
    CoalesceEvent(coalesced_, event);  // over the rate: kept for the next frame
    last_event_seq_ = event.seq();
    coalesced_arrival_ = arrival;
    ServerMetrics().EventCoalesced();
  }
  if (changes_picture) preempt_ = true;  // a still frame in progress is moot
}

void Session::NoteMisfitLocked() {
  const std::string& preset = current_.scene().transfer_function().preset();
  if (!stream_ || preset.empty() || misfits_noted_.count(preset)) return;
  const std::string misfit = PresetMisfit(preset, *volume_->volume());
  if (misfit.empty()) return;
  misfits_noted_.insert(preset);
  stream_->SendNotice(v1::Notice::WARNING, misfit);
}

void Session::ApplyCoalescedLocked() {
  std::map<int, v1::SessionEvent> events;
  events.swap(coalesced_);
  for (const auto& [kind, event] : events) ApplyLocked(event, coalesced_arrival_);
}

unsigned Session::ApplyLocked(const v1::SessionEvent& event, Clock::time_point arrival) {
  const v1::Viewport viewport = current_.viewport();
  const std::uint64_t applied_seq = current_.last_event_seq();
  const unsigned changes = ApplyEvent(current_, event, scene_context_, context_.limits);  // as it was if it throws
  const std::uint64_t pixels = std::uint64_t(current_.viewport().width()) * current_.viewport().height();
  if (pixels != pixels_) {
    try {
      context_.pixels->Exchange(pixels_, pixels);
    } catch (const LimitExceeded& e) {
      // Only a resize changes the size: put the old one back.
      *current_.mutable_viewport() = viewport;
      current_.mutable_scene()->mutable_render()->set_width(viewport.width());
      current_.mutable_scene()->mutable_render()->set_height(viewport.height());
      current_.set_last_event_seq(applied_seq);
      throw LimitExceeded(e.flag(), fmt::format("event {}: resize: {}", event.seq(), e.what()));
    }
    pixels_ = pixels;
    SetStepPixelsLocked(pixels_, render_scale_);
  }
  if (changes & kStreamChanged) settings_ = SessionFrameSettings(context_.backend, current_.stream());
  if (changes & kTransferFunctionChanged) NoteMisfitLocked();
  if (changes & kPhaseChanged) {  // playing starts over from the phase it names
    play_from_ = int(current_.scene().time().phase());
    play_since_ = arrival;
  }
  // Every event but a pause gets a frame that answers it. Only an attached
  // session pauses or resumes: one without a stream (SendEvents before a
  // watch, or after the end) keeps its state, so that it still expires.
  if (stream_ && event.has_pause()) {
    state_ = State::kPaused;
  } else if (stream_ && (event.has_resume() || state_ == State::kIdle)) {
    state_ = State::kRendering;
  }
  if (!event.has_pause() && !event.has_resume()) dirty_ = true;
  changes_ |= changes & kEverythingChanged;
  state_unsent_ = true;
  if (event.has_pause() && stream_) SendStateLocked();  // no frame follows to carry it
  last_event_seq_ = std::max(last_event_seq_, event.seq());
  last_event_arrival_ = arrival;
  event_unrendered_ = true;
  return changes;
}

int Session::PhaseDueLocked(Clock::time_point now) const {
  const double elapsed = std::chrono::duration<double>(now - play_since_).count();
  return PhaseAt(current_.scene().time(), play_from_, elapsed, volume_->phase_seconds(), volume_->phases());
}

void Session::MakePipeline() {
  // A time series' phases stay on the device beside the pipeline, for its phase switches (PhaseCopies: all, or
  // a window ahead); a still volume's one copy, and the second volume's, are the renderer's alone (the cache
  // counts each holder as a renderer).
  if (volume_->phases() > 1) {
    const int device = context_.scheduler->gpu().value_or(kHostDevice);
    const int window = PhaseCopies::Window(*volume_, device, context_.limits->max_phase_copy_bytes);
    phase_copies_ = std::make_unique<PhaseCopies>(*volume_, device, window, context_.setup, id_, pipeline_phase_);
  }
  pipeline_ = std::make_unique<FramePipeline>(context_.backend, volume_->phase(pipeline_phase_), kSessionRenderer,
                                              volume_->labels());
  if (fused_) pipeline_->SetFusedVolume(fused_->volume());
  prepared_.clear();
  pipeline_->SetCancel(&cancel_);
  pipeline_->SetPreempt(&preempt_);
  pipeline_->SetJpegEncoder(context_.jpeg_encoder);
}

void Session::DropPipeline() {
  pipeline_.reset();
  phase_copies_.reset();
  prepared_.clear();  // the device memory goes with the pipeline
}

void Session::SendStateLocked() {
  if (stream_) stream_->SendState(current_);
  for (const Watcher& w : watchers_) w.stream->SendState(current_);
  state_unsent_ = false;
}

void Session::End(const grpc::Status& status) {
  {
    std::lock_guard lock(mu_);
    if (state_ == State::kEnded) return;
    state_ = State::kEnded;
    end_reason_ = status.ok() ? "it was closed" : status.error_message();
    cancel_ = true;
    for (auto& still : stills_) {
      if (auto flag = still.lock()) *flag = true;
    }
    stills_.clear();
    if (stream_) {
      sent_before_ += stream_->frames_sent();
      dropped_before_ += stream_->frames_dropped();
      stream_->EndSession(status);
    }
    stream_ = nullptr;
    for (const Watcher& w : watchers_) w.stream->EndSession(status);
    watchers_.clear();
  }
  if (status.ok()) {
    spdlog::info("session {}: closed", id_);
  } else {
    spdlog::warn("session {}: ended: {}", id_, LogSafe(status.error_message()));
  }
  context_.on_end(id_);
  Wake();  // the next step frees the device memory
}

void Session::Drain() {
  {
    std::lock_guard lock(mu_);
    const std::string notice =
        "the server is shutting down (draining): this stream ends now; reconnect to another server";
    if (stream_) stream_->SendNotice(v1::Notice::WARNING, notice);
    for (const Watcher& w : watchers_) w.stream->SendNotice(v1::Notice::WARNING, notice);
  }
  End(RpcError::Unavailable("the server is shutting down").status());
}

void Session::BeginStill(const std::shared_ptr<std::atomic<bool>>& flag) {
  std::lock_guard lock(mu_);
  ++stills_rendering_;
  if (state_ == State::kEnded) {
    *flag = true;
    return;
  }
  std::erase_if(stills_, [](const auto& still) { return still.expired(); });
  stills_.push_back(flag);
}

void Session::EndStill() {
  {
    std::lock_guard lock(mu_);
    stills_rendering_ = std::max(0, stills_rendering_ - 1);
    if (state_ == State::kStarting || state_ == State::kDetached) since_ = Clock::now();
  }
  Wake();  // refinement waited for the still
}

std::string Session::EndReason() const {
  std::lock_guard lock(mu_);
  return end_reason_;
}

void Session::CurrentScene(v1::Scene& scene, FrameSettings& settings) const {
  std::lock_guard lock(mu_);
  scene = current_.scene();
  scene.mutable_time()->set_phase(std::uint32_t(PhaseDueLocked(Clock::now())));  // where a playing series is
  settings = settings_;
}

bool Session::CanRenderLocked() const {
  if (state_ != State::kRendering || encodes_in_flight_ >= kMaxEncodesInFlight || stream_->SlotFull()) return false;
  // While a still of this session renders, its refinement waits (EndStill
  // wakes it): on a CPU the two would share the cores for minutes, and the
  // still is the better picture of the same view. Events still get frames.
  return stills_rendering_ == 0 || dirty_ || event_unrendered_ || !coalesced_.empty();
}

void Session::SetStepPixelsLocked(std::uint64_t viewport_pixels, float render_scale) {
  render_scale_ = render_scale;
  const std::int64_t pixels = std::int64_t(double(viewport_pixels) * render_scale * render_scale);
  context_.scheduler->AddSessionPixels(pixels - step_pixels_.exchange(pixels));
}

bool Session::Step() {
  Work work;
  bool release = false;
  grpc::Status bad_event;
  {
    std::lock_guard lock(mu_);
    if (stream_ && !coalesced_.empty()) bad_event = Guarded([&] { ApplyCoalescedLocked(); });
    if (!bad_event.ok()) {
      release = true;
    } else if (!stream_) {  // detached or ended
      release = true;
      holds_device_memory_ = false;
    } else if (!CanRenderLocked()) {
      return false;
    } else {
      if (state_unsent_) SendStateLocked();  // before the frame that shows it
      work.update = dirty_;
      if (dirty_) {
        work.scene = current_.scene();
        work.changes = std::exchange(changes_, 0u);
        dirty_ = false;
      }
      work.settings = settings_;
      work.phase = PhaseDueLocked(Clock::now());
      work.stamp.frame_id = next_frame_id_++;
      work.stamp.event_seq = last_event_seq_;
      work.stamp.answers_event = event_unrendered_;
      work.stamp.origin = last_event_arrival_;
      event_unrendered_ = false;
      preempt_ = false;  // this frame takes every event so far
      ++encodes_in_flight_;
      holds_device_memory_ = true;
    }
  }
  if (release) {
    DropPipeline();
    if (!bad_event.ok()) End(bad_event);
    return false;
  }
  const Clock::time_point render_start = Clock::now();
  if (work.stamp.answers_event) {
    work.stamp.queue_us = MicrosBetween(work.stamp.origin, render_start);
  } else {
    work.stamp.origin = render_start;
  }
  DisplayFrame frame;
  try {
    if (!pipeline_) {
      pipeline_phase_ = work.phase;
      MakePipeline();
    }
    if (work.phase != pipeline_phase_) {
      if (phase_copies_) phase_copies_->ShowFrom(work.phase);
      pipeline_->SetPhase(volume_->phase(work.phase));
      pipeline_phase_ = work.phase;
    }
    if (work.update) pipeline_->Update(work.scene, work.settings, work.changes);
    frame = pipeline_->RenderFrame();
  } catch (const Cancelled&) {  // the session ended or its stream went: nobody waits for this frame
    DropPipeline();
    std::lock_guard lock(mu_);
    --encodes_in_flight_;
    holds_device_memory_ = false;
    dirty_ = true;  // a new pipeline takes the scene again
    return false;
  } catch (...) {
    DropPipeline();  // whatever it held may be broken: give the memory back now
    {
      std::lock_guard lock(mu_);
      --encodes_in_flight_;
      holds_device_memory_ = false;
    }
    End(ToStatus(std::current_exception()));
    return false;
  }
  if (frame.preempted) {  // a newer event made it moot: the next step renders that
    std::lock_guard lock(mu_);
    --encodes_in_flight_;
    if (next_frame_id_ == work.stamp.frame_id + 1) next_frame_id_ = work.stamp.frame_id;  // no gap for the viewer
    return CanRenderLocked();
  }
  ++context_.scheduler->frames_rendered;
  ServerMetrics().FrameRendered();
  ServerMetrics().ObserveStage(Stage::kRender, frame.render_ms / 1000.0);
  if (work.settings.denoiser.method != DenoiseMethod::kNone) {
    ServerMetrics().ObserveStage(Stage::kDenoise, frame.denoise_ms / 1000.0);
  }
  ServerMetrics().ObserveStage(Stage::kTonemap, frame.display_ms / 1000.0);
  {
    std::lock_guard lock(mu_);
    ++frames_rendered_;
    accumulated_spp_ = frame.accumulated_spp;
    SetStepPixelsLocked(pixels_, frame.resolution_scale);
    // An event during the render still gets its frame; a playing series
    // renders on for its next phase.
    if (frame.final && !event_unrendered_ && !PlayingLocked() && state_ == State::kRendering) state_ = State::kIdle;
  }
  work.stamp.phase = std::uint32_t(work.phase);
  Encode(std::move(frame), work.stamp);  // at the settings' chroma and quality, as displayed
  std::lock_guard lock(mu_);
  return CanRenderLocked();
}

void Session::Encode(DisplayFrame display, const FrameStamp& stamp) {
  context_.encoder->Submit([self = shared_from_this(), display = std::move(display), stamp]() {
    // Idle encoder threads mean idle cores: a lone session's frame encodes
    // in bands on them and reaches its viewer sooner; a busy pool encodes whole.
    const int bands = std::min(1 + self->context_.encoder->idle(), kMaxJpegBands);
    v1::Frame frame;
    try {
      frame = EncodeFrame(display, stamp, bands);
    } catch (...) {
      {
        std::lock_guard lock(self->mu_);
        --self->encodes_in_flight_;
      }
      self->End(ToStatus(std::current_exception()));
      return;
    }
    self->Deliver(std::move(frame), stamp.origin);
  });
}

void Session::Deliver(v1::Frame frame, Clock::time_point origin) {
  {
    std::lock_guard lock(mu_);
    --encodes_in_flight_;
    if (stream_ && frame.frame_id() > last_offered_id_) {
      last_offered_id_ = frame.frame_id();
      // Encoded once: each watcher's slot gets the same bytes.
      for (const Watcher& w : watchers_) w.stream->OfferFrame(frame, origin);
      if (!watchers_.empty()) newest_frame_ = frame;  // for the next watcher, from the first on
      stream_->OfferFrame(std::move(frame), origin);
    } else {
      ++frames_stale_;
      ServerMetrics().FrameDropped();
    }
  }
  Wake();
}

v1::SessionStatus Session::Status() const {
  std::lock_guard lock(mu_);
  v1::SessionStatus s;
  s.set_session_id(id_);
  s.set_owner(owner_);
  s.set_volume_id(volume_->id());
  s.set_device(context_.scheduler->name());
  *s.mutable_viewport() = current_.viewport();
  switch (state_) {
    case State::kStarting:
      s.set_state(v1::SessionStatus::STARTING);
      break;
    case State::kIdle:
      s.set_state(v1::SessionStatus::IDLE);
      break;
    case State::kPaused:
      s.set_state(v1::SessionStatus::PAUSED);
      break;
    case State::kDetached:
    case State::kEnded:
      s.set_state(v1::SessionStatus::DETACHED);
      break;
    default:
      s.set_state(v1::SessionStatus::RENDERING);
      break;
  }
  s.set_frames_rendered(frames_rendered_);
  s.set_frames_sent(sent_before_ + (stream_ ? stream_->frames_sent() : 0));
  s.set_frames_dropped(dropped_before_ + frames_stale_ + (stream_ ? stream_->frames_dropped() : 0));
  s.set_accumulated_spp(accumulated_spp_);
  s.set_last_event_seq(last_event_seq_);
  s.set_holds_device_memory(holds_device_memory_);
  return s;
}

bool Session::Expired(Clock::time_point now, Clock::duration detached, Clock::duration unattached) const {
  std::lock_guard lock(mu_);
  if (stills_rendering_ > 0) return false;
  if (state_ == State::kStarting) return now - since_ > unattached;
  return state_ == State::kDetached && now - since_ > detached;
}

bool Session::ended() const {
  std::lock_guard lock(mu_);
  return state_ == State::kEnded;
}

}  // namespace cinevol::service

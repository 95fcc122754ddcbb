// A session: one viewer's scene, settings and frame pipeline. Events from the
// viewer's stream merge into the scene (the latest camera wins); the
// session's scheduler calls Step, which renders one frame when there is
// something to show and room to send it, and hands it to the encoder pool;
// the encoded frame goes to the attached stream's newest-wins slot, and to
// the slot of every watcher of a shared session (docs/sharing.md): rendered
// and encoded once, a slow watcher drops frames and never slows the others.
//
// Device memory (the pipeline) exists only while a stream is attached: when
// the stream ends the next step frees it, and a later attach rebuilds it.
#pragma once

#include <grpcpp/support/status.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "cinevol/v1/service.pb.h"
#include "pipeline/frame_pipeline.h"
#include "runtime/frame_encoding.h"
#include "runtime/phase_copies.h"
#include "runtime/scheduler.h"
#include "runtime/task_pool.h"
#include "runtime/token_bucket.h"
#include "runtime/volume_registry.h"
#include "scene/session_state.h"

namespace cinevol::service {

using Clock = std::chrono::steady_clock;

// Events a session takes in, a second, at most this many times
// --max-events-per-second: StreamSession paces its reads so, SendEvents
// refuses past it. The session coalesces those past --max-events-per-second.
inline constexpr int kReadPacing = 4;
// Pointer moves a second one sender may share (docs/sharing.md).
inline constexpr int kPointerRate = 30;

// The write side of the stream attached to a session: one write in flight,
// and behind it one slot where a newer frame replaces an older one.
class FrameStream {
 public:
  virtual ~FrameStream() = default;
  // Writes `frame` now, or parks it in the slot while a write is in flight.
  // `origin`: when the work this frame answers began (for timings.server_us).
  virtual void OfferFrame(v1::Frame frame, Clock::time_point origin) = 0;
  virtual void SendNotice(v1::Notice::Level level, std::string message) = 0;
  // The session's state after events changed it, before the frame showing them.
  virtual void SendState(v1::SessionState state) = 0;
  // A frame waits in the slot (or the stream is ending): render nothing more.
  virtual bool SlotFull() const = 0;
  // Finishes the call with `status` after the write in flight.
  virtual void End(grpc::Status status) = 0;
  // The same where the session itself ended (closed, drained, failed): the
  // call's trailers say so, and a client knows not to attach to it again.
  virtual void EndSession(grpc::Status status) = 0;
  virtual std::uint64_t frames_sent() const = 0;
  virtual std::uint64_t frames_dropped() const = 0;
};

// The viewport pixels of every session together (--max-total-pixels): the
// device memory sessions take grows with them.
class PixelBudget {
 public:
  explicit PixelBudget(std::uint64_t limit) : limit_(limit) {}
  // Gives back `release` pixels and takes `take`; throws ResourceExhausted
  // (changing nothing) when that would pass the limit.
  void Exchange(std::uint64_t release, std::uint64_t take);
  std::uint64_t used() const;

 private:
  const std::uint64_t limit_;
  mutable std::mutex mu_;
  std::uint64_t used_ = 0;
};

// What sessions share: where they render and encode, the limits, the volumes.
struct SessionContext {
  Scheduler* scheduler = nullptr;
  TaskPool* encoder = nullptr;
  Backend backend = Backend::kCpu;
  JpegEncoderKind jpeg_encoder = JpegEncoderKind::kCpu;  // ChooseJpegEncoder's, once per server
  const SessionLimits* limits = nullptr;
  MapResolver resolve_map;        // environment maps: inside the data roots
  PixelBudget* pixels = nullptr;  // the session holds its viewport's pixels from creation to destruction
  std::function<void(const std::string& session_id)> on_end;  // the registry forgets it
  TaskPool* setup = nullptr;  // builds a time series' phases ahead (PhaseCopies); null: at once
};

// The session's volume prepared on `scheduler`'s device (its brick ranges,
// a float volume quantised, the voxels uploaded to a GPU), as its renderer
// will ask for it: shared with every session of that volume there, built by
// the first. A time series' phases as far as `phase_budget` bytes hold them
// (PhaseCopies::Window: every phase, or the first window), so that a phase
// switch finds them there. Slow for a large volume, so CreateSession calls it
// off the frame and the gRPC threads; throws ResourceExhausted when it does
// not fit, LimitExceeded when the budget holds fewer than two phases. The
// second volume a session fuses (`fused`, or null) too.
std::vector<std::shared_ptr<const VolumeCopy>> PrepareOnDevice(const VolumeLease& volume, const VolumeLease* fused,
                                                               const Scheduler& scheduler, std::uint64_t phase_budget);

class Session final : public Job, public std::enable_shared_from_this<Session> {
 public:
  // `state`: InitialState's, its stream settings all set (ToStreamSettings).
  // `prepared`: PrepareOnDevice's, held until the first frame's pipeline holds its own.
  // `fused`: the second volume the state's Scene.fusion may name, or null.
  Session(std::string id, std::string owner, std::shared_ptr<VolumeLease> volume, std::shared_ptr<VolumeLease> fused,
          v1::SessionState state, SessionContext context, std::vector<std::shared_ptr<const VolumeCopy>> prepared = {});
  ~Session() override;

  const std::string& id() const { return id_; }
  const std::string& owner() const { return owner_; }

  // From the stream's reactor. Attach makes `stream` the session's (a
  // previous stream ends with ABORTED); Detach forgets it and frees the
  // device memory; OnWritable says a write finished.
  void Attach(FrameStream* stream);
  void Detach(FrameStream* stream);
  // A watcher of a shared session, by grant `grant_id`: it gets every state
  // and every frame delivered from now on (the newest at once), never paces
  // rendering and never takes the session over. Throws NOT_FOUND once the
  // session ended, RESOURCE_EXHAUSTED past --max-viewers-per-session.
  // `holder`: who watches (Grant::holder()), whose pointer goes when its last stream does.
  void AttachWatcher(FrameStream* stream, const std::string& grant_id, const std::string& holder);
  // Ends the watchers by `grant_id` with `status` (revoked, expired); returns how many.
  int EndWatchers(const std::string& grant_id, const grpc::Status& status);
  // Streams open by `grant_id` now.
  int Watching(const std::string& grant_id) const;
  // Who drives the session now, for every stream's state (the owner, or a
  // presenter grant's holder).
  void SetPresenter(const std::string& who);
  // `who`'s pointer (the owner, a grant's holder), shared with every stream
  // at once. Past kPointerRate a second from one sender, moves are dropped.
  void OnPointer(const std::string& who, const v1::Pointer& pointer, Clock::time_point arrival);
  void OnWritable(FrameStream* stream);
  // Applies an event (scene/session_state.h's ApplyEvent, this server's
  // limits); throws InputError (or RpcError) for a bad one. Events
  // past the stream's rate are coalesced (the latest camera, lights,
  // transfer function and resize win; render and stream settings merge) and
  // applied once, before the next frame.
  void OnEvent(const v1::SessionEvent& event, Clock::time_point arrival);
  // SendEvents' batch: each event in order as OnEvent takes it; returns the
  // state after them (coalesced events not yet in it). Unlike the stream,
  // which ends the session on a bad event, a bad event here throws and leaves
  // the session as the events before it made it: the caller hears the error
  // in its answer. A batch past kReadPacing x --max-events-per-second a
  // second is refused whole (RESOURCE_EXHAUSTED): unary calls have no paced
  // reads, and would otherwise cost the session's lock a check or merge for
  // every event a client can send. Events before an attach change the scene
  // (the attach sends it); pause and resume only matter to an attached stream.
  // `from_grant`: a presenter's batch (docs/sharing.md): the session numbers
  // its events itself, after the newest it has, and answers their numbers in
  // the state; the owner's numbering goes on undisturbed.
  v1::SessionState OnEvents(const google::protobuf::RepeatedPtrField<v1::SessionEvent>& events,
                            Clock::time_point arrival, bool from_grant = false);
  // The state now, as the streams get it.
  v1::SessionState CurrentState() const;
  // Ends the session: the stream finishes with `status`, memory is freed and
  // the registry forgets it. Later calls do nothing.
  void End(const grpc::Status& status);

  // Ends the session on SIGTERM: a notice to the stream, then UNAVAILABLE.
  void Drain();
  // A still of this session begins: `flag` (its cancel) is raised when the
  // session ends, now if it has. Until EndStill the session does not expire:
  // a snapshot's own session (created, never attached) would otherwise be
  // reaped under it (--unattached-session-seconds).
  void BeginStill(const std::shared_ptr<std::atomic<bool>>& flag);
  // The still is done; the expiry clock of a session without a stream starts again.
  void EndStill();
  // Why the session ended (its status message); empty while it lives.
  std::string EndReason() const;

  // What a snapshot renders: the current scene and settings, a time series
  // at the phase it shows now (Scene.time.phase; while playing, the clock's).
  void CurrentScene(v1::Scene& scene, FrameSettings& settings) const;
  const std::shared_ptr<VolumeLease>& volume() const { return volume_; }
  // The second volume the session began with (Scene.fusion names it), or null.
  const std::shared_ptr<VolumeLease>& fused() const { return fused_; }
  Scheduler* scheduler() const { return context_.scheduler; }
  v1::SessionStatus Status() const;
  // Detached for longer than `detached`, or never attached for longer than
  // `unattached`, with no still rendering.
  bool Expired(Clock::time_point now, Clock::duration detached, Clock::duration unattached) const;
  bool ended() const;

  bool Step() override;
  // The viewport at the last frame's resolution scale (interactive frames).
  std::int64_t StepPixels() const override { return step_pixels_.load(std::memory_order_relaxed); }

 private:
  struct Work;
  void SetStepPixelsLocked(std::uint64_t viewport_pixels, float render_scale);
  bool CanRenderLocked() const;
  // OnEvent's work, mu_ held; throws for a bad event.
  void OnEventLocked(v1::SessionEvent event, Clock::time_point arrival, bool from_grant = false);
  // Applies one event now and returns what it changed (ApplyEvent's bits);
  // throws for a bad one (the scene stays as it was).
  unsigned ApplyLocked(const v1::SessionEvent& event, Clock::time_point arrival);
  // Warns the stream, once a session for each preset, where the scene's
  // transfer-function preset does not fit the volume (PresetMisfit).
  void NoteMisfitLocked();
  // Applies the coalesced events; ends nothing, throws for a bad one.
  void ApplyCoalescedLocked();
  // Sends current_ to every stream: the owner's (when attached) and the watchers'.
  void SendStateLocked();
  void PointLocked(const std::string& who, const v1::Pointer& pointer, Clock::time_point arrival);
  void AddWatcher(FrameStream* stream, const std::string& grant_id, const std::string& holder);
  // The encode stage (frame_encoding.h) on the encoder pool, then Deliver.
  void Encode(DisplayFrame frame, const FrameStamp& stamp);
  void Deliver(v1::Frame frame, Clock::time_point origin);
  void Wake() { context_.scheduler->Wake(shared_from_this()); }
  // The phase a frame begun at `now` shows: Scene.time's, or while playing
  // where the clock has reached since it began.
  int PhaseDueLocked(Clock::time_point now) const;
  bool PlayingLocked() const { return current_.scene().time().playing() && volume_->phases() > 1; }
  // Builds the pipeline, and holds every phase's device copy beside it.
  void MakePipeline();
  void DropPipeline();

  const std::string id_, owner_;
  const std::shared_ptr<VolumeLease> volume_;
  const std::shared_ptr<VolumeLease> fused_;
  const SessionContext context_;
  const SceneContext scene_context_;  // what ApplyEvent resolves the scene against: the volume as leased

  mutable std::mutex mu_;
  FrameStream* stream_ = nullptr;
  struct Watcher {
    FrameStream* stream;
    std::string grant_id, holder;
  };
  std::vector<Watcher> watchers_;
  // The newest frame delivered, for a watcher that joins (kept once the
  // session has had a watcher: an unshared session pays nothing for it).
  std::optional<v1::Frame> newest_frame_;
  std::map<std::string, TokenBucket> pointer_rates_;  // by who: a pointer's moves past its rate are dropped
  v1::SessionState current_;                          // what events made of the session; its stream settings all set
  FrameSettings settings_;                            // current_.stream() on this backend
  bool dirty_ = true;                                 // current_ changed since the pipeline last saw it
  bool state_unsent_ = true;                          // current_ changed since the stream last got it
  unsigned changes_ = kEverythingChanged;             // SceneChange bits since the pipeline last saw the scene
  // Where the session is in its life. kRendering, kIdle and kPaused have a
  // stream attached (stream_ set); the others do not.
  enum class State {
    kStarting,   // created; no stream attached yet
    kRendering,  // frames go out: events to answer or refinement under way
    kIdle,       // refined to target_spp; nothing to render until an event
    kPaused,     // no frames until resume (a new attach resumes too)
    kDetached,   // its stream went; kept for a new attach until it expires
    kEnded,
  };
  State state_ = State::kStarting;
  std::uint64_t last_event_seq_ = 0;
  std::uint64_t last_owner_seq_ = 0;  // the owner's numbering (the stream's or its SendEvents')
  Clock::time_point last_event_arrival_;
  bool event_unrendered_ = false;  // an event arrived since the last frame began
  Clock::time_point since_;        // creation or last detach
  int encodes_in_flight_ = 0;
  std::uint64_t next_frame_id_ = 1;
  std::uint64_t last_offered_id_ = 0;
  std::uint64_t frames_rendered_ = 0;
  std::uint64_t frames_stale_ = 0;                      // finished encoding after a newer frame: never sent
  std::uint64_t sent_before_ = 0, dropped_before_ = 0;  // by streams that ended
  int accumulated_spp_ = 0;
  bool holds_device_memory_ = false;
  std::uint64_t pixels_ = 0;                   // held in the context's PixelBudget
  float render_scale_ = 1;                     // the last frame's resolution scale
  std::atomic<std::int64_t> step_pixels_{0};   // pixels_ x render_scale_^2: StepPixels
  TokenBucket events_;                         // events applied at once; past it, coalesced
  TokenBucket batched_;                        // SendEvents' events: kReadPacing x --max-events-per-second
  std::map<int, v1::SessionEvent> coalesced_;  // by SessionEvent::KindCase, oldest first applied
  std::set<std::string> misfits_noted_;        // presets NoteMisfitLocked warned of
  Clock::time_point coalesced_arrival_;
  // Playing (Scene.time.playing): from which phase, since when.
  int play_from_ = 0;
  Clock::time_point play_since_;

  // Raised when the session ends or its stream goes: the frame in flight stops.
  std::atomic<bool> cancel_{false};
  // Raised by an event that changes the picture, lowered when a frame takes
  // the events: a still CPU frame in flight stops (FramePipeline::SetPreempt).
  std::atomic<bool> preempt_{false};
  std::vector<std::weak_ptr<std::atomic<bool>>> stills_;  // raised when the session ends
  int stills_rendering_ = 0;                              // BeginStill without EndStill: the session does not expire
  std::string end_reason_;

  // Touched only inside Step: the pipeline, the phase it shows, and a time
  // series' phase copies while it lives (from creation to the first
  // pipeline: PrepareOnDevice's, for any volume).
  std::unique_ptr<FramePipeline> pipeline_;
  int pipeline_phase_ = 0;
  std::unique_ptr<PhaseCopies> phase_copies_;
  std::vector<std::shared_ptr<const VolumeCopy>> prepared_;
};

}  // namespace cinevol::service

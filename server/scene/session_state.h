// A session's state and every rule of what events do to it: the one place
// that says what an event means (runtime/ keeps the queues and the pacing).
// The server applies events with its limits and answers with the state they
// produced (ServerMessage.state), resolved: named views as numbers, presets
// as points, the volume's placement given, so that no client works any of
// it out again. Problems throw InputError naming the field ("event 7:
// camera.eye.x: ..."), OverLimit where a limit of this server is what the
// request breaks.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <string>

#include "cinevol/v1/service.pb.h"
#include "core/labels.h"
#include "core/volume.h"
#include "scene/scene_file.h"

namespace cinevol {

// What one session may ask for; `cinevol-server --help` names the flags and
// docs/security.md gives the defaults and why.
struct SessionLimits {
  std::uint64_t max_pixels = 3840 * 2160;        // width x height of a viewport
  int max_frame_spp = 256;                       // samples per pixel of one streamed frame
  std::uint64_t max_frame_samples = 1ull << 25;  // spp x pixels of one streamed frame
  int max_bounces = 64;
  int max_snapshot_spp = 16384;
  std::uint64_t max_snapshot_samples = 1ull << 31;  // spp x pixels of one still
  std::uint64_t max_movie_samples = 1ull << 37;     // frames x spp x pixels of one movie: 2,000 720p frames at 64 spp
  int default_snapshot_spp = 256;
  int max_tf_points = 256;  // transfer-function control points
  int max_lights = 16;
  int max_events_per_second = 240;   // per stream; past it events are coalesced
  int max_viewers_per_session = 50;  // streams watching a shared session (docs/sharing.md)
  int max_viewers_per_grant = 25;    // of them by one grant: a link never takes every seat
  // Device memory a session holds in a time series' phase copies: past it
  // the phases ahead are kept in a window (runtime/phase_copies.h).
  std::uint64_t max_phase_copy_bytes = 4096ull << 20;
};

// What an event changed: SceneChange bits, and these.
enum SessionChange : unsigned {
  kStreamChanged = 1u << 7,        // stream settings (denoiser, quality, budgets, refinement)
  kPauseChanged = 1u << 8,         // paused or resumed
  kMeasurementsChanged = 1u << 9,  // the reader's measurements: shared at once, no frame answers them
  kPointersChanged = 1u << 10,     // someone's pointer: the same
  kPhaseChanged = 1u << 11,        // a time series' phase shown, or its playing (Scene.time)
};

// The server's path for a light's environment map named in `field`: only
// inside its data roots (it throws otherwise). Empty: names stay as written.
using MapResolver = std::function<std::string(const std::string& map, const std::string& field)>;

// What a session's scene is resolved against.
struct SceneContext {
  const Volume& volume;
  // Its segmentation (or only its table) when the session began, where it
  // has one: label styles need a segmentation; named views frame labels.
  const LabelVolume* labels = nullptr;
  std::string volume_id = {};    // for messages
  MapResolver resolve_map = {};  // empty: environment map names stay as written
  int phases = 1;                // a time series' phases (Scene.time)
  // The second volume the session began with (Scene.fusion.volume_id names
  // it), where it has one; null: a scene may fuse none.
  const Volume* fused = nullptr;
  std::string fused_id = {};
};

// The state a new session starts from: the request's scene or preset (else
// the volume's default preset), its viewport and stream settings, defaults
// filled, validated against `limits`, then resolved: a scene without lights
// gets the volume's default lights, presets become points, a named view
// becomes numbers (framing scans the volume's blocks: milliseconds to
// seconds for 512^3), and the placement is the volume's.
v1::SessionState InitialState(const v1::CreateSessionRequest& request, const SceneContext& context,
                              const SessionLimits& limits);

// What InitialState resolves after its checks, for a scene rendered
// without a session (in the volume-centred frame, defaults filled): its
// presets as points and its named view as numbers.
void ResolveSceneModel(v1::Scene& scene, const SceneContext& context);

// Applies `event` to `state` and returns what changed (SceneChange and
// SessionChange bits; 0 where it changed nothing). Only the parts the event
// touches are defaulted, validated and resolved. `limits`: null checks the
// scene's own ranges only. Throws, leaving `state` as it was.
unsigned ApplyEvent(v1::SessionState& state, const v1::SessionEvent& event, const SceneContext& context,
                    const SessionLimits* limits);

// `who`'s pointer on the shared view (SessionState.pointers, by who), or
// hidden; kPointersChanged, or 0 where nothing changed. Throws InputError
// for a position outside the frame.
unsigned ApplyPointer(v1::SessionState& state, const std::string& who, const v1::Pointer& pointer);
// Hides `who`'s pointer (they left); kPointersChanged where it was shown.
unsigned HidePointer(v1::SessionState& state, const std::string& who);

// Events past the event rate wait, unchecked, for the next frame: each kind
// keeps its latest, render and stream settings merged (set fields change,
// as ApplyEvent does). `waiting` is by SessionEvent::kind_case.
void CoalesceEvent(std::map<int, v1::SessionEvent>& waiting, const v1::SessionEvent& event);

// Checks the fields `edit` sets; `field` prefixes messages.
void CheckStreamSettings(const v1::StreamSettings& edit, const std::string& field);

// The snapshot's samples per pixel (default filled), checked against the
// limits for a still of `pixels` pixels.
int SnapshotSpp(const v1::SnapshotRequest& request, std::uint64_t pixels, const SessionLimits& limits);

// The request that creates a session in `state` again, on `volume_id`.
v1::CreateSessionRequest RecreateRequest(const v1::SessionState& state, const std::string& volume_id);

}  // namespace cinevol

// A session's state and what events do to it: the one place that says what
// an event means. The server applies events with its limits and answers
// with the state they produced (ServerMessage.state); the client library
// applies the same rules to events the server has not answered yet, so that
// a session re-created elsewhere (failover) is the one its viewer saw.
// Problems throw InputError naming the field ("event 7: camera.eye.x: ..."),
// OverLimit where a limit of this server is what the request breaks.
#pragma once

#include <cstdint>
#include <functional>
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
  int default_snapshot_spp = 256;
  int max_tf_points = 256;                       // transfer-function control points
  int max_lights = 16;
  int max_events_per_second = 240;               // per stream; past it events are coalesced
  int max_viewers_per_session = 50;              // streams watching a shared session (docs/sharing.md)
  int max_viewers_per_grant = 25;                // of them by one grant: a link never takes every seat
};

// What an event changed: SceneChange bits, and these.
enum SessionChange : unsigned {
  kStreamChanged = 1u << 6,  // stream settings (denoiser, quality, budgets, refinement)
  kPauseChanged = 1u << 7,   // paused or resumed
};

// The server's path for a light's environment map named in `field`: only
// inside its data roots (it throws otherwise). Empty: names stay as written.
using MapResolver = std::function<std::string(const std::string& map, const std::string& field)>;

// The state a new session starts from: the request's scene or preset (else
// the volume's default preset), its viewport and stream settings, defaults
// filled, validated against `limits`; a scene without lights gets the
// volume's default lights. Its camera is not resolved yet (AddResolvedCamera).
v1::SessionState InitialState(const v1::CreateSessionRequest& request, const Volume& volume,
                              const SessionLimits& limits, const MapResolver& resolve_map = {});

// Fills a named view's eye, target and up (the view stays set) with what it
// resolves to for `volume`, framing what the scene shows.
void AddResolvedCamera(v1::Scene& scene, const Volume& volume, const LabelVolume* labels);

// Applies `event` to `state` and returns what changed (SceneChange and
// SessionChange bits; 0 where it changed nothing). Only the parts the event
// touches are defaulted and validated. `limits`: null checks the scene's own
// ranges only (a client that does not know the server's limits). Throws,
// leaving `state` as it was.
unsigned ApplyEvent(v1::SessionState& state, const v1::SessionEvent& event, const SessionLimits* limits,
                    const MapResolver& resolve_map = {});

// Checks the fields `edit` sets; `field` prefixes messages.
void CheckStreamSettings(const v1::StreamSettings& edit, const std::string& field);

// The snapshot's samples per pixel (default filled), checked against the
// limits for a still of `pixels` pixels.
int SnapshotSpp(const v1::SnapshotRequest& request, std::uint64_t pixels, const SessionLimits& limits);

// The request that creates a session in `state` again, on `volume_id`.
v1::CreateSessionRequest RecreateRequest(const v1::SessionState& state, const std::string& volume_id);

}  // namespace cinevol

// What a session request may say, checked before anything acts on it, and
// how events merge into a session's scene and settings. Problems throw
// InputError naming the field ("viewport.width: ...", "event 7: camera.eye.x:
// ..."); the service answers INVALID_ARGUMENT with that message.
#pragma once

#include <cstdint>

#include "cinevol/v1/service.pb.h"
#include "core/volume.h"
#include "pipeline/frame_pipeline.h"
#include "service/volume_registry.h"

namespace cinevol::service {

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
};

// Fills a named view's eye, target and up (the view stays set) with what it
// resolves to for `volume`.
void AddResolvedCamera(v1::Scene& scene, const Volume& volume, const LabelVolume* labels);

// The scene a new session starts from: the request's scene or preset, its
// viewport, defaults filled, validated; environment maps resolved inside the
// data roots.
v1::Scene InitialScene(const v1::CreateSessionRequest& request, const Volume& volume, const SessionLimits& limits,
                       const VolumeRegistry& volumes);

// `settings` with the fields `edit` sets; `field` prefixes messages.
FrameSettings MergeStreamSettings(FrameSettings settings, const v1::StreamSettings& edit, const std::string& field);

// Applies one event to `scene` and `settings` (both unchanged when it
// throws); pause and resume change neither.
void ApplyEvent(const v1::SessionEvent& event, v1::Scene& scene, FrameSettings& settings,
                const SessionLimits& limits, const VolumeRegistry& volumes);

// The snapshot's samples per pixel (default filled), checked against the
// limits for a still of `pixels` pixels.
int SnapshotSpp(const v1::SnapshotRequest& request, std::uint64_t pixels, const SessionLimits& limits);

}  // namespace cinevol::service

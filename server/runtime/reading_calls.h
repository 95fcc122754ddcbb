// The reading tools on a session (SessionService.RenderSlice and Pick):
// the request's fields to the reading module's settings, the session's scene
// and volume to what they read, and the answer back (docs/reading.md).
#pragma once

#include <atomic>

#include "cinevol/v1/scene.pb.h"
#include "cinevol/v1/service.pb.h"
#include "pacs/frame_plane.h"
#include "reading/slice.h"
#include "runtime/volume_registry.h"

namespace cinevol::service {

// What `request` asks of a slice of `volume`. Throws InputError naming the
// request's field.
SliceSpec SliceSpecOf(const v1::SliceRequest& request, const Volume& volume);

// A slice of `volume` (a time series' at the scene's phase) through the
// scene's labels, its second volume's overlay (Scene.fusion; `fused` the
// session's, or null) and (on request) clipping, encoded as PNG. Throws
// InputError naming the request's field; Cancelled once `cancel` is raised
// (the caller gone, the deadline passed: a thick slab stops early).
// `threads`: at most this many render it (0: all).
v1::SliceImage SliceOf(const v1::SliceRequest& request, const v1::Scene& scene, const VolumeLease& volume,
                       const VolumeLease* fused, const std::atomic<bool>* cancel = nullptr, int threads = 0);

// A frame of a DICOM image (PacsService.RenderFrame): `plane`'s pixel grid,
// or its field of view fitted within request.viewport in square pixels,
// sampled from `volume` through the request's window (no labels, no
// clipping). Throws InputError naming the request's field.
v1::SliceImage FrameOf(const v1::RenderFrameRequest& request, const pacs::FramePlane& plane, const Volume& volume,
                       const std::atomic<bool>* cancel = nullptr, int threads = 0);

// What lies under pixel (request.x, request.y) of the scene's camera and
// viewport (a time series' at the scene's phase), the second volume the
// scene fuses included (`fused`, or null). Throws InputError naming the
// request's field.
v1::PickResult PickOn(const v1::PickRequest& request, const v1::Scene& scene, const VolumeLease& volume,
                      const VolumeLease* fused);

}  // namespace cinevol::service

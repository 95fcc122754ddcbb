// A movie's path (SessionService.RenderMovie): how a still scene changes from
// frame to frame. The camera turns about its target (an orbit), a clip plane
// moves across a patient axis through the volume (a sweep), or a time series
// plays its phases (a loop).
#pragma once

#include <vector>

#include "cinevol/v1/scene.pb.h"
#include "cinevol/v1/service.pb.h"
#include "core/volume.h"

namespace cinevol {

inline constexpr int kMaxMovieFrames = 3600;  // two minutes at 30 frames/s: a movie, not a stream

// The request's frame count (seconds x fps), or InputError naming what is out of range.
int MovieFrames(const v1::MovieRequest& request);
// Its frames a second: MovieRequest.fps, or 25 where unset.
inline int MovieFps(const v1::MovieRequest& request) { return request.fps() == 0 ? 25 : int(request.fps()); }

// What a movie is of: the session's volume (a time series' first phase), its
// phases and their times from the first (empty where the series gives none).
struct MovieVolume {
  const Volume& volume;
  int phases = 1;
  const std::vector<double>& phase_seconds;
};

// Frame `frame` of `frames`: `start` (a session's scene, volume-centred) along the request's path. On a sweep the
// plane is in patient coordinates, as clipping is; on a loop, frame k shows the phase playing reaches k / fps
// seconds after Scene.time.phase. Throws InputError for a path the volume cannot take.
v1::Scene MovieFrame(const v1::Scene& start, const v1::MovieRequest& request, const MovieVolume& volume, int frame,
                     int frames);

}  // namespace cinevol

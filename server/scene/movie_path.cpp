#include "scene/movie_path.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "core/error.h"
#include "scene/time_series.h"

namespace cinevol {
namespace {

constexpr int kMaxClipPlanes = 6;  // Clipping.planes

struct Vec3d {
  double v[3];
};

Vec3d Of(const v1::Vec3& p) { return {{p.x(), p.y(), p.z()}}; }
v1::Vec3 Message(const Vec3d& p) {
  v1::Vec3 m;
  m.set_x(float(p.v[0]));
  m.set_y(float(p.v[1]));
  m.set_z(float(p.v[2]));
  return m;
}
double Dot(const Vec3d& a, const Vec3d& b) { return a.v[0] * b.v[0] + a.v[1] * b.v[1] + a.v[2] * b.v[2]; }
Vec3d Cross(const Vec3d& a, const Vec3d& b) {
  return {{a.v[1] * b.v[2] - a.v[2] * b.v[1], a.v[2] * b.v[0] - a.v[0] * b.v[2], a.v[0] * b.v[1] - a.v[1] * b.v[0]}};
}
Vec3d Plus(const Vec3d& a, const Vec3d& b, double s = 1) {
  return {{a.v[0] + s * b.v[0], a.v[1] + s * b.v[1], a.v[2] + s * b.v[2]}};
}
Vec3d Scaled(const Vec3d& a, double s) { return {{a.v[0] * s, a.v[1] * s, a.v[2] * s}}; }

// Rodrigues: `v` turned by `radians` about unit axis `k`.
Vec3d Turned(const Vec3d& v, const Vec3d& k, double radians) {
  const double c = std::cos(radians), s = std::sin(radians);
  return Plus(Plus(Scaled(v, c), Cross(k, v), s), k, Dot(k, v) * (1 - c));
}

// The fraction of the path at `frame`: 0 to 1, except that a loop stops one step short of its start.
double Along(int frame, int frames, bool loop) {
  return frames == 1 ? 0 : double(frame) / double(loop ? frames : frames - 1);
}

void Orbit(v1::Camera& camera, double degrees, double t) {
  const Vec3d target = Of(camera.target()), up = Of(camera.up());
  const double up_length = std::sqrt(Dot(up, up));
  if (!(up_length > 0)) throw InputError("orbit_degrees: the session's camera has no up direction to turn about");
  const Vec3d eye = Plus(target, Turned(Plus(Of(camera.eye()), target, -1), Scaled(up, 1 / up_length),
                                        degrees * t * std::numbers::pi / 180));
  camera.set_view(v1::NAMED_VIEW_UNSPECIFIED);
  *camera.mutable_eye() = Message(eye);
}

// The smallest and largest patient coordinate along `axis` of the volume's voxel centres.
std::pair<double, double> Extent(const Volume& volume, int axis) {
  const VolumeMetadata& m = volume.metadata();
  double lo = m.origin_mm[axis], hi = lo;
  for (int corner = 1; corner < 8; ++corner) {
    double at = m.origin_mm[axis];
    for (int c = 0; c < 3; ++c) {
      if (corner & (1 << c)) at += m.direction[3 * axis + c] * (volume.dims()[c] - 1) * volume.spacing_mm()[c];
    }
    lo = std::min(lo, at);
    hi = std::max(hi, at);
  }
  return {lo, hi};
}

int SweepAxis(v1::SliceAxis axis) {
  switch (axis) {
    case v1::SAGITTAL:
      return 0;
    case v1::CORONAL:
      return 1;
    case v1::AXIAL:
    case v1::SLICE_AXIS_UNSPECIFIED:
      return 2;
    default:
      throw InputError(fmt::format("sweep: {} is not AXIAL, CORONAL or SAGITTAL", int(axis)));
  }
}

// A plane across the patient axis from the volume's far end to its near one, keeping what lies beyond it: the cut
// moves through the volume and the last frame cuts none of it. It joins the scene's own clipping.
void Sweep(v1::Clipping& clipping, const Volume& volume, int axis, double t) {
  if (clipping.planes_size() >= kMaxClipPlanes) {
    throw InputError(fmt::format("sweep: the scene already has {} clip planes, the most it can", kMaxClipPlanes));
  }
  const auto [lo, hi] = Extent(volume, axis);
  Vec3d point{{volume.metadata().origin_mm[0], volume.metadata().origin_mm[1], volume.metadata().origin_mm[2]}};
  Vec3d normal{{0, 0, 0}};
  point.v[axis] = hi - (hi - lo) * t;
  normal.v[axis] = 1;
  v1::ClipPlane& plane = *clipping.add_planes();
  *plane.mutable_point() = Message(point);
  *plane.mutable_normal() = Message(normal);
  plane.set_cap(true);
}

// The phase frame `frame` shows: where playing from the scene's phase reaches at the frame's time.
void Loop(v1::Time& time, const MovieVolume& volume, double elapsed_s) {
  if (volume.phases < 2) throw InputError("phases: the session's volume is not a time series (one phase)");
  time.set_playing(true);
  time.set_phase(std::uint32_t(PhaseAt(time, int(time.phase()), elapsed_s, volume.phase_seconds, volume.phases)));
  time.set_playing(false);  // a still of that phase
}

}  // namespace

int MovieFrames(const v1::MovieRequest& request) {
  const int fps = MovieFps(request);
  if (fps > 60) throw InputError(fmt::format("fps: {} is outside [1, 60]", request.fps()));
  const double frames = std::round(request.seconds() * fps);
  if (!(frames >= 1 && frames <= kMaxMovieFrames)) {
    throw InputError(fmt::format("seconds: {:g} s at {} frames/s is {:g} frames; a movie has 1 to {}",
                                 request.seconds(), fps, frames, kMaxMovieFrames));
  }
  switch (request.path_case()) {
    case v1::MovieRequest::kOrbitDegrees:
      if (!(std::abs(request.orbit_degrees()) <= 3600)) {
        throw InputError(fmt::format("orbit_degrees: {:g} is outside [-3600, 3600]", request.orbit_degrees()));
      }
      break;
    case v1::MovieRequest::kSweep:
      SweepAxis(request.sweep());
      break;
    case v1::MovieRequest::kPhases:
      if (!request.phases()) throw InputError("phases: give true to play the phases, or another path");
      break;
    default:
      throw InputError("path: give orbit_degrees, sweep or phases");
  }
  return int(frames);
}

v1::Scene MovieFrame(const v1::Scene& start, const v1::MovieRequest& request, const MovieVolume& volume, int frame,
                     int frames) {
  v1::Scene scene = start;
  switch (request.path_case()) {
    case v1::MovieRequest::kOrbitDegrees: {
      const double degrees = request.orbit_degrees();
      Orbit(*scene.mutable_camera(), degrees, Along(frame, frames, std::abs(degrees) >= 360));
      break;
    }
    case v1::MovieRequest::kPhases:
      // A thousandth of a frame in: where frames fall on phase boundaries (10 frames/s on phases 0.1 s apart),
      // float times from the file would otherwise put some a phase early.
      Loop(*scene.mutable_time(), volume, (frame + 1e-3) / MovieFps(request));
      break;
    default:
      Sweep(*scene.mutable_clipping(), volume.volume, SweepAxis(request.sweep()), Along(frame, frames, false));
  }
  return scene;
}

}  // namespace cinevol

// Reprojection for the temporal denoisers (paper, Sec. 6): a pixel's motion
// comes from its first real collision seen by the previous camera; pixels
// whose rays escaped move with their direction. Per-pixel, host and device.
#pragma once

#include "core/camera.h"
#include "core/hd.h"
#include "core/vec.h"

namespace cinevol {

// What reprojection reads: this frame's and the previous frame's first hits
// and cameras.
struct ReprojectionView {
  const Vec4f* first_hit = nullptr;       // this frame
  const Vec4f* prev_first_hit = nullptr;  // previous frame
  Camera camera, prev_camera;
  int width = 0, height = 0;
  bool has_history = false;
  // Nothing moved or changed since the previous frame: every pixel is its own
  // history, whatever its rays hit this time (at a few samples a pixel on a
  // semi-transparent edge may escape in one frame and hit in the next).
  bool still = false;
  // The camera moved, turned or zoomed since the previous frame (not just the
  // shading changed): what a pixel shows is then followed by its hit's motion.
  bool camera_moved = false;
  float max_error_px = 2.0f;  // round trip tolerance

  CINEVOL_HD int Index(int x, int y) const { return y * width + x; }
  CINEVOL_HD bool InBounds(int x, int y) const { return x >= 0 && y >= 0 && x < width && y < height; }
};

struct Reprojection {
  bool valid = false;
  float x = 0, y = 0;  // continuous pixel coordinates in the previous frame (centres at integers)
  int nx = 0, ny = 0;  // nearest previous pixel
};

CINEVOL_HD bool Escaped(const Vec4f& hit) { return hit.w == 0.0f; }

// Where camera `to` sees world point p, the hit found through the pixel
// centred at (cx, cy) of camera `from` (continuous pixel coordinates).
// That hit comes from one of the pixel's jittered samples, up to 1.5 pixels
// from its centre (the Gaussian pixel filter), so its own projection carries
// that jitter. Where the camera moved (`follow_motion`) the pixel's centre
// moves by the hit's motion instead (its two projections' difference): the
// history is read where the pixel was, +0.14 to +0.62 dB at 720p on the
// study's orbits and sun and sky. Where the camera stood and the shading
// moved, the jittered position is kept on purpose: it reads the history
// between pixels (a half-pixel blur a frame) and the round trip sends a few
// pixels back to no history, which both denoisers lean on there (reading it
// exactly loses up to 0.65 dB under moving lights; docs/tradeoff.md,
// "The hit's motion where the camera moved").
CINEVOL_HD bool Follow(const Camera& from, const Camera& to, bool follow_motion, Vec3f p, float cx, float cy, float& px,
                       float& py) {
  if (!to.Project(p, px, py)) return false;
  if (!follow_motion) return true;
  float fx, fy;
  if (!from.Project(p, fx, fy)) return false;
  px = cx + (px - fx);
  py = cy + (py - fy);
  return true;
}

// Where pixel (x, y) was in the previous frame. Valid when it was on screen,
// the previous pixel there saw the same kind of thing (volume or background)
// and, for the volume, the previous pixel's own hit maps back within
// max_error_px of (x, y): a round trip that tolerates the depth noise of
// semi-transparent media (a still view always maps back exactly) and
// rejects disocclusions. Pixels whose rays escaped move with the direction
// through their centre.
CINEVOL_HD Reprojection Reproject(const ReprojectionView& v, int x, int y) {
  Reprojection r;
  if (!v.has_history) return r;
  if (v.still) {
    r.x = float(x);
    r.y = float(y);
    r.nx = x;
    r.ny = y;
    r.valid = true;
    return r;
  }
  const Vec4f hit = v.first_hit[v.Index(x, y)];
  const float cx = float(x) + 0.5f, cy = float(y) + 0.5f;
  float px, py;
  if (Escaped(hit)) {
    const Vec3f d = v.camera.GenerateRay(cx, cy, 0.5f, 0.5f).direction;
    if (!v.prev_camera.Project(v.prev_camera.eye + d, px, py)) return r;
  } else if (!Follow(v.camera, v.prev_camera, v.camera_moved, Xyz(hit), cx, cy, px, py)) {
    return r;
  }
  r.x = px - 0.5f;
  r.y = py - 0.5f;
  r.nx = static_cast<int>(floorf(px));
  r.ny = static_cast<int>(floorf(py));
  if (!v.InBounds(r.nx, r.ny)) return r;
  const Vec4f prev = v.prev_first_hit[v.Index(r.nx, r.ny)];
  if (Escaped(prev) != Escaped(hit)) return r;
  if (!Escaped(hit)) {
    float bx, by;
    if (!Follow(v.prev_camera, v.camera, v.camera_moved, Xyz(prev), float(r.nx) + 0.5f, float(r.ny) + 0.5f, bx, by)) {
      return r;
    }
    const float ex = bx - cx, ey = by - cy;
    if (ex * ex + ey * ey > v.max_error_px * v.max_error_px) return r;
  }
  r.valid = true;
  return r;
}

// How far what pixel (x, y) shows moved on screen since the previous frame,
// in pixels: its first hit (or, where its rays escaped, its direction) seen
// by both cameras. 0 where the camera did not move; infinite where the
// previous camera did not see it.
CINEVOL_HD float ScreenMotion(const ReprojectionView& v, int x, int y) {
  const Vec4f hit = v.first_hit[v.Index(x, y)];
  Vec3f p = Xyz(hit), p_prev = p;
  if (Escaped(hit)) {  // the background is at infinity: it moves with the cameras' turn, not their step
    const Vec3f d = v.camera.GenerateRay(float(x) + 0.5f, float(y) + 0.5f, 0.5f, 0.5f).direction;
    p = v.camera.eye + d;
    p_prev = v.prev_camera.eye + d;
  }
  float cx, cy, px, py;
  if (!v.camera.Project(p, cx, cy) || !v.prev_camera.Project(p_prev, px, py)) return INFINITY;
  return sqrtf((px - cx) * (px - cx) + (py - cy) * (py - cy));
}

// The bilinear taps of a valid reprojection r: the four previous pixels
// around its continuous position, each weighed where it saw the same kind of
// thing as `hit` (0 elsewhere; a still view: the pixel itself). Histories
// read at one position share them (Sample). The taps are unrolled, so they
// stay in registers on the GPU.
struct HistoryTaps {
  int index[4] = {};
  float weight[4] = {};
  float total = 0.0f;

  CINEVOL_HD HistoryTaps(const ReprojectionView& v, const Reprojection& r, const Vec4f& hit) {
    if (v.still) {
      index[0] = v.Index(r.nx, r.ny);
      weight[0] = total = 1.0f;
      return;
    }
    const int x0 = static_cast<int>(floorf(r.x)), y0 = static_cast<int>(floorf(r.y));
    const float fx = r.x - float(x0), fy = r.y - float(y0);
    CINEVOL_UNROLL
    for (int k = 0; k < 4; ++k) {
      const int dx = k & 1, dy = k >> 1, sx = x0 + dx, sy = y0 + dy;
      if (!v.InBounds(sx, sy) || Escaped(v.prev_first_hit[v.Index(sx, sy)]) != Escaped(hit)) continue;
      index[k] = v.Index(sx, sy);
      weight[k] = fmaxf((dx ? fx : 1.0f - fx) * (dy ? fy : 1.0f - fy), 0.0f);
      total += weight[k];
    }
  }

  // The history at the position: false where no tap saw the same kind of thing.
  template <class T>
  CINEVOL_HD bool Sample(const T* history, T& out) const {
    if (!(total > 0.0f)) return false;
    T sum{};
    CINEVOL_UNROLL
    for (int k = 0; k < 4; ++k) {
      if (weight[k] > 0.0f) sum = sum + history[index[k]] * weight[k];
    }
    out = sum * (1.0f / total);
    return true;
  }
};

}  // namespace cinevol

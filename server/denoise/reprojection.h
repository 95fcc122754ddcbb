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

// Where pixel (x, y) was in the previous frame. Valid when it was on screen,
// the previous pixel there saw the same kind of thing (volume or background)
// and, for the volume, the previous pixel's own hit maps back within
// max_error_px of (x, y): a round trip that tolerates the depth noise of
// semi-transparent media (a still view always maps back exactly) and
// rejects disocclusions.
// The position is where the hit projects, so it carries the jitter of the
// sample that found it (up to 1.5 pixels): a half-pixel blur of the
// histories a frame, and a few random resets under moving shading. Moving
// the pixel's centre by the hit's motion instead gains where the camera
// moves but loses up to 0.65 dB at 720p where it stands and the lights move
// (docs/tradeoff.md, "Reprojection by the hit's motion").
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
  float px, py;
  if (Escaped(hit)) {
    const Vec3f d = v.camera.GenerateRay(float(x) + 0.5f, float(y) + 0.5f, 0.5f, 0.5f).direction;
    if (!v.prev_camera.Project(v.prev_camera.eye + d, px, py)) return r;
  } else if (!v.prev_camera.Project(Xyz(hit), px, py)) {
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
    if (!v.camera.Project(Xyz(prev), bx, by)) return r;
    const float ex = bx - (float(x) + 0.5f), ey = by - (float(y) + 0.5f);
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

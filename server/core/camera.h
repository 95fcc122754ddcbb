// A thin-lens camera: generates primary rays and projects world points back
// to pixels (the denoiser's reprojection uses the same projection).
#pragma once

#include "core/sampling.h"
#include "core/vec.h"

namespace cinevol {

struct Ray {
  Vec3f origin;
  Vec3f direction;  // unit length
};

struct Camera {
  Vec3f eye;                      // mm
  Vec3f forward, right, up;       // orthonormal, right = forward x up
  float tan_half_fov_y = 0.27f;   // tan(fov_y / 2)
  float lens_radius = 0.0f;       // mm; 0 = pinhole
  float focal_distance = 1.0f;    // mm along forward
  int width = 1, height = 1;      // pixels

  CINEVOL_HD float aspect() const { return float(width) / float(height); }

  // Ray through continuous pixel position (px, py) (pixel (x, y) covers
  // [x, x+1) x [y, y+1), y down) via lens point (lens_u, lens_v) in [0,1)^2.
  CINEVOL_HD Ray GenerateRay(float px, float py, float lens_u, float lens_v) const {
    const float sx = (2.0f * px / float(width) - 1.0f) * tan_half_fov_y * aspect();
    const float sy = (1.0f - 2.0f * py / float(height)) * tan_half_fov_y;
    const Vec3f dir = Normalize(forward + right * sx + up * sy);
    if (lens_radius <= 0.0f) return {eye, dir};
    // Points on the plane of focus stay sharp; the origin moves on the lens.
    const Vec3f focus = eye + dir * (focal_distance / Dot(dir, forward));
    float lx, ly;
    SampleConcentricDisk(lens_u, lens_v, lx, ly);
    const Vec3f origin = eye + right * (lx * lens_radius) + up * (ly * lens_radius);
    return {origin, Normalize(focus - origin)};
  }

  // Continuous pixel position of world point p; false when p is behind the
  // camera. Inverse of GenerateRay for a pinhole.
  CINEVOL_HD bool Project(Vec3f p, float& px, float& py) const {
    const Vec3f d = p - eye;
    const float z = Dot(d, forward);
    if (z <= 1e-6f) return false;
    const float sx = Dot(d, right) / (z * tan_half_fov_y * aspect());
    const float sy = Dot(d, up) / (z * tan_half_fov_y);
    px = 0.5f * (sx + 1.0f) * float(width);
    py = 0.5f * (1.0f - sy) * float(height);
    return true;
  }
};

// True when a and b project every point to the same pixel (the lens aside).
inline bool SameProjection(const Camera& a, const Camera& b) {
  return a.eye == b.eye && a.forward == b.forward && a.right == b.right && a.up == b.up &&
         a.tan_half_fov_y == b.tan_half_fov_y && a.width == b.width && a.height == b.height;
}

// Builds a camera looking from eye at target; up need not be orthogonal.
inline Camera LookAt(Vec3f eye, Vec3f target, Vec3f up, float fov_y_deg, int width, int height) {
  Camera c;
  c.eye = eye;
  c.forward = Normalize(target - eye);
  c.right = Normalize(Cross(c.forward, up));
  c.up = Cross(c.right, c.forward);
  c.tan_half_fov_y = tanf(0.5f * fov_y_deg * kPi / 180.0f);
  c.focal_distance = Length(target - eye);
  c.width = width;
  c.height = height;
  return c;
}

}  // namespace cinevol

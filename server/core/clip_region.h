// The part of the volume a scene keeps: the intersection of half-spaces, in
// world mm (the volume's frame, centred at the origin). A crop box is six of
// them and each clip plane one more. An intersection of half-spaces is
// convex, so a ray meets it in one interval: clipping a ray's interval
// through the volume box is exact, and bricks cut away are never visited.
#pragma once

#include "core/hd.h"
#include "core/vec.h"

namespace cinevol {

// A crop box (6) and up to 6 clip planes.
inline constexpr int kMaxClipHalfSpaces = 12;

struct ClipRegion {
  // Keeps the points x with Dot(xyz, x) + w >= 0: xyz points into the kept side.
  Vec4f half_spaces[kMaxClipHalfSpaces] = {};
  int count = 0;
  // Bit i: half-space i's face is capped, where it cuts tissue a surface.
  unsigned capped = 0;

  // Narrows [t0, t1] along o + t d to the kept part; false where none is left.
  // `entered` is the half-space whose face the interval now starts on, or -1.
  CINEVOL_HD bool Clip(Vec3f o, Vec3f d, float& t0, float& t1, int* entered = nullptr) const {
    if (entered) *entered = -1;
    for (int i = 0; i < count; ++i) {
      const Vec3f n = Xyz(half_spaces[i]);
      const float inside = Dot(n, o) + half_spaces[i].w;  // > 0 where o is kept
      const float rate = Dot(n, d);
      if (rate > 0.0f) {
        const float t = -inside / rate;
        if (t > t0) {
          t0 = t;
          if (entered) *entered = i;
        }
      } else if (rate < 0.0f) {
        t1 = fminf(t1, -inside / rate);
      } else if (inside < 0.0f) {
        return false;  // parallel to the plane, on the side cut away
      }
    }
    return t0 < t1;
  }
};

}  // namespace cinevol

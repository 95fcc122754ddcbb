// Measurements between picked points (patient LPS mm): a distance and an
// angle, what a reader lists beside the image.
#pragma once

#include <cmath>

#include "core/sampling.h"
#include "core/vec.h"

namespace cinevol {

// The distance between two points, in mm.
inline float DistanceMm(Vec3f a, Vec3f b) { return Length(b - a); }

// The angle at `vertex` between the directions to `a` and `b`, in degrees
// [0, 180]; 0 when either point is the vertex (no direction to measure).
// atan2 of |cross| and dot keeps its precision near 0 and 180 degrees, where
// acos of the cosine loses it.
inline float AngleDeg(Vec3f a, Vec3f vertex, Vec3f b) {
  const Vec3f u = a - vertex, v = b - vertex;
  if (Dot(u, u) == 0.0f || Dot(v, v) == 0.0f) return 0.0f;
  return std::atan2(Length(Cross(u, v)), Dot(u, v)) * (180.0f / kPi);
}

}  // namespace cinevol

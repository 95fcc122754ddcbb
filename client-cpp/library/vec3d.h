// Three-vectors in double precision for what a client works out on its side
// (view_math.h, placement.h): millimetres and directions, the numbers the
// page's twins (web/src/vec.ts) compute with, so both meet one set of golden
// cases to the same tolerance.
#pragma once

#include <cmath>

#include "cinevol/v1/scene.pb.h"

namespace cinevol {

struct Vec3d {
  double x = 0, y = 0, z = 0;

  double operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  double& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
  bool operator==(const Vec3d&) const = default;
};

inline Vec3d operator+(Vec3d a, Vec3d b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Vec3d operator-(Vec3d a, Vec3d b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Vec3d operator-(Vec3d a) { return {-a.x, -a.y, -a.z}; }
inline Vec3d operator*(Vec3d a, double s) { return {a.x * s, a.y * s, a.z * s}; }
inline Vec3d operator*(double s, Vec3d a) { return a * s; }
inline Vec3d operator/(Vec3d a, double s) { return {a.x / s, a.y / s, a.z / s}; }
inline Vec3d& operator+=(Vec3d& a, Vec3d b) { return a = a + b; }

inline double Dot(Vec3d a, Vec3d b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3d Cross(Vec3d a, Vec3d b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
inline double Length(Vec3d a) { return std::sqrt(Dot(a, a)); }
// The zero vector stays zero (as web/src/vec.ts's norm), rather than NaN.
inline Vec3d Normalized(Vec3d a) {
  const double length = Length(a);
  return length > 0 ? a / length : a;
}

inline Vec3d ToVec3d(const v1::Vec3& v) { return {v.x(), v.y(), v.z()}; }
inline v1::Vec3 ToProto(Vec3d v) {
  v1::Vec3 out;
  out.set_x(float(v.x));
  out.set_y(float(v.y));
  out.set_z(float(v.z));
  return out;
}

}  // namespace cinevol

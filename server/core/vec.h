// Small vector types for host and device code: positions in mm, directions,
// linear RGB colours.
#pragma once

#include <cmath>
#include <cstdint>

#include "core/hd.h"

namespace cinevol {

using std::isfinite;

struct Vec3f {
  float x = 0, y = 0, z = 0;

  CINEVOL_HD float operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  CINEVOL_HD float& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
};

// Four floats, 16-byte aligned so the GPU loads them in one instruction.
struct alignas(16) Vec4f {
  float x = 0, y = 0, z = 0, w = 0;
};

struct Vec3i {
  int x = 0, y = 0, z = 0;

  CINEVOL_HD int operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  CINEVOL_HD int& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
};

CINEVOL_HD Vec3f operator+(Vec3f a, Vec3f b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
CINEVOL_HD Vec3f operator-(Vec3f a, Vec3f b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
CINEVOL_HD Vec3f operator-(Vec3f a) { return {-a.x, -a.y, -a.z}; }
CINEVOL_HD Vec3f operator*(Vec3f a, Vec3f b) { return {a.x * b.x, a.y * b.y, a.z * b.z}; }
CINEVOL_HD Vec3f operator/(Vec3f a, Vec3f b) { return {a.x / b.x, a.y / b.y, a.z / b.z}; }
CINEVOL_HD Vec3f operator*(Vec3f a, float s) { return {a.x * s, a.y * s, a.z * s}; }
CINEVOL_HD Vec3f operator*(float s, Vec3f a) { return {a.x * s, a.y * s, a.z * s}; }
CINEVOL_HD Vec3f operator/(Vec3f a, float s) { return a * (1.0f / s); }
CINEVOL_HD Vec3f& operator+=(Vec3f& a, Vec3f b) { return a = a + b; }
CINEVOL_HD Vec3f& operator*=(Vec3f& a, Vec3f b) { return a = a * b; }
CINEVOL_HD Vec3f& operator*=(Vec3f& a, float s) { return a = a * s; }
CINEVOL_HD bool operator==(Vec3f a, Vec3f b) { return a.x == b.x && a.y == b.y && a.z == b.z; }
CINEVOL_HD bool operator==(Vec3i a, Vec3i b) { return a.x == b.x && a.y == b.y && a.z == b.z; }

CINEVOL_HD int MinInt(int a, int b) { return a < b ? a : b; }
CINEVOL_HD int MaxInt(int a, int b) { return a > b ? a : b; }

CINEVOL_HD float Dot(Vec3f a, Vec3f b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
CINEVOL_HD Vec3f Cross(Vec3f a, Vec3f b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
CINEVOL_HD float Length(Vec3f a) { return sqrtf(Dot(a, a)); }
CINEVOL_HD Vec3f Normalize(Vec3f a) { return a / Length(a); }
CINEVOL_HD Vec3f Min(Vec3f a, Vec3f b) { return {fminf(a.x, b.x), fminf(a.y, b.y), fminf(a.z, b.z)}; }
CINEVOL_HD Vec3f Max(Vec3f a, Vec3f b) { return {fmaxf(a.x, b.x), fmaxf(a.y, b.y), fmaxf(a.z, b.z)}; }
CINEVOL_HD Vec3f Abs(Vec3f a) { return {fabsf(a.x), fabsf(a.y), fabsf(a.z)}; }
CINEVOL_HD float MaxComponent(Vec3f a) { return fmaxf(a.x, fmaxf(a.y, a.z)); }
CINEVOL_HD float MinComponent(Vec3f a) { return fminf(a.x, fminf(a.y, a.z)); }
CINEVOL_HD Vec3f Lerp(Vec3f a, Vec3f b, float t) { return a + (b - a) * t; }
CINEVOL_HD float Luminance(Vec3f rgb) { return 0.2126f * rgb.x + 0.7152f * rgb.y + 0.0722f * rgb.z; }
// & rather than &&: no short-circuit, so the three tests need no branch (on
// bools: the device's isfinite may return any non-zero int for true).
CINEVOL_HD bool IsFinite(Vec3f a) {
  const bool x = isfinite(a.x), y = isfinite(a.y), z = isfinite(a.z);
  return x & y & z;
}
CINEVOL_HD Vec4f operator+(Vec4f a, Vec4f b) { return {a.x + b.x, a.y + b.y, a.z + b.z, a.w + b.w}; }
CINEVOL_HD Vec3f Xyz(Vec4f a) { return {a.x, a.y, a.z}; }
CINEVOL_HD Vec4f ToVec4(Vec3f a, float w) { return {a.x, a.y, a.z, w}; }
CINEVOL_HD Vec3f ToFloat(Vec3i a) {
  return {static_cast<float>(a.x), static_cast<float>(a.y), static_cast<float>(a.z)};
}

// An orthonormal basis around n (Duff et al. 2017, "Building an Orthonormal
// Basis, Revisited"): no branches on near-parallel axes, no NaN.
CINEVOL_HD void OrthonormalBasis(Vec3f n, Vec3f& t, Vec3f& b) {
  const float sign = copysignf(1.0f, n.z);
  const float a = -1.0f / (sign + n.z);
  const float c = n.x * n.y * a;
  t = {1.0f + sign * n.x * n.x * a, sign * c, -sign * n.x};
  b = {c, sign + n.y * n.y * a, -n.y};
}

}  // namespace cinevol

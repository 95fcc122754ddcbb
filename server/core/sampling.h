// Warping uniform samples to the distributions the path tracer draws from,
// each with its pdf. Tests check every pdf against a histogram.
#pragma once

#include <cmath>

#include "core/hd.h"
#include "core/vec.h"

namespace cinevol {

inline constexpr float kPi = 3.14159265358979323846f;
inline constexpr float kInvPi = 0.31830988618379067154f;
inline constexpr float kInv4Pi = 0.07957747154594766788f;

CINEVOL_HD float Clamp(float v, float lo, float hi) { return fminf(fmaxf(v, lo), hi); }
CINEVOL_HD float Sqr(float v) { return v * v; }
CINEVOL_HD float SafeSqrt(float v) { return sqrtf(fmaxf(v, 0.0f)); }

// sin and cos of pi x, for the sampled angles (x within [-2, 2]). On a GPU
// one sincospif: reducing x is exact, so it carries none of the rarely taken
// reduction path (arguments beyond 10^5) that sinf and cosf each inline.
CINEVOL_HD void SinCosPi(float x, float& s, float& c) {
#if CINEVOL_DEVICE_PASS
  sincospif(x, &s, &c);
#else
  s = sinf(kPi * x);
  c = cosf(kPi * x);
#endif
}

CINEVOL_HD Vec3f SampleUniformSphere(float u1, float u2) {
  const float z = 1.0f - 2.0f * u1;
  const float r = SafeSqrt(1.0f - z * z);
  float s, c;
  SinCosPi(2.0f * u2, s, c);
  return {r * c, r * s, z};
}
CINEVOL_HD float UniformSpherePdf() { return kInv4Pi; }

// Shirley-Chiu concentric map of [0,1)^2 onto the unit disk.
CINEVOL_HD void SampleConcentricDisk(float u1, float u2, float& x, float& y) {
  const float a = 2.0f * u1 - 1.0f, b = 2.0f * u2 - 1.0f;
  if (a == 0.0f && b == 0.0f) {
    x = y = 0.0f;
    return;
  }
  float r, turns;  // the angle over pi
  if (fabsf(a) > fabsf(b)) {
    r = a;
    turns = 0.25f * (b / a);
  } else {
    r = b;
    turns = 0.5f - 0.25f * (a / b);
  }
  float s, c;
  SinCosPi(turns, s, c);
  x = r * c;
  y = r * s;
}

// Cosine-weighted direction around +z.
CINEVOL_HD Vec3f SampleCosineHemisphere(float u1, float u2) {
  float x, y;
  SampleConcentricDisk(u1, u2, x, y);
  return {x, y, SafeSqrt(1.0f - x * x - y * y)};
}
CINEVOL_HD float CosineHemispherePdf(float cos_theta) { return fmaxf(cos_theta, 0.0f) * kInvPi; }

// Henyey-Greenstein phase function. Convention: wo points away from the
// scattering point towards where light goes (the viewer), wi towards where it
// comes from; g > 0 scatters forward, i.e. wi near -wo.
CINEVOL_HD float HenyeyGreenstein(float cos_theta, float g) {
  const float denom = 1.0f + g * g + 2.0f * g * cos_theta;
  return kInv4Pi * (1.0f - g * g) / (denom * SafeSqrt(denom));
}

// Samples wi for HG given wo; the pdf equals the phase value.
CINEVOL_HD Vec3f SampleHenyeyGreenstein(Vec3f wo, float g, float u1, float u2) {
  float cos_theta;
  if (fabsf(g) < 1e-3f) {
    cos_theta = 1.0f - 2.0f * u1;
  } else {
    cos_theta = -1.0f / (2.0f * g) * (1.0f + g * g - Sqr((1.0f - g * g) / (1.0f + g - 2.0f * g * u1)));
  }
  cos_theta = Clamp(cos_theta, -1.0f, 1.0f);
  const float sin_theta = SafeSqrt(1.0f - cos_theta * cos_theta);
  float sin_phi, cos_phi;
  SinCosPi(2.0f * u2, sin_phi, cos_phi);
  Vec3f t, b;
  OrthonormalBasis(wo, t, b);
  // cos_theta is measured between wo and wi as HenyeyGreenstein(Dot(wo, wi)).
  return t * (sin_theta * cos_phi) + b * (sin_theta * sin_phi) + wo * cos_theta;
}

// Inverse error function (Giles 2010, single precision): for the Gaussian
// pixel filter on both host and device.
CINEVOL_HD float ErfInv(float x) {
  float w = -logf(fmaxf((1.0f - x) * (1.0f + x), 1e-30f));
  float p;
  if (w < 5.0f) {
    w -= 2.5f;
    p = 2.81022636e-08f;
    p = 3.43273939e-07f + p * w;
    p = -3.5233877e-06f + p * w;
    p = -4.39150654e-06f + p * w;
    p = 0.00021858087f + p * w;
    p = -0.00125372503f + p * w;
    p = -0.00417768164f + p * w;
    p = 0.246640727f + p * w;
    p = 1.50140941f + p * w;
  } else {
    w = sqrtf(w) - 3.0f;
    p = -0.000200214257f;
    p = 0.000100950558f + p * w;
    p = 0.00134934322f + p * w;
    p = -0.00367342844f + p * w;
    p = 0.00573950773f + p * w;
    p = -0.0076224613f + p * w;
    p = 0.00943887047f + p * w;
    p = 1.00167406f + p * w;
    p = 2.83297682f + p * w;
  }
  return p * x;
}

// Offset in pixels drawn from a Gaussian of standard deviation sigma,
// truncated at +-radius: the pixel filter, importance sampled.
CINEVOL_HD float SampleTruncatedGaussian(float u, float sigma, float radius) {
  // Map u into the CDF range of [-radius, radius] and invert.
  const float edge = erff(radius / (sigma * 1.41421356f));
  return sigma * 1.41421356f * ErfInv((2.0f * u - 1.0f) * edge);
}

// Power heuristic (beta = 2) for multiple importance sampling.
CINEVOL_HD float PowerHeuristic(float pdf_a, float pdf_b) {
  const float a = pdf_a * pdf_a, b = pdf_b * pdf_b;
  return a + b > 0.0f ? a / (a + b) : 0.0f;
}

}  // namespace cinevol

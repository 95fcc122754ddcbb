// Lights as kernels see them: rectangular area lights, point and directional
// lights, and one environment (uniform, gradient sky or an importance-sampled
// HDR map). World space is mm; directions are unit vectors.
#pragma once

#include <cstdint>
#include <vector>

#include "core/hd.h"
#include "core/image.h"
#include "core/sampling.h"
#include "core/vec.h"

namespace cinevol {

enum class LightKind : std::int32_t { kArea, kPoint, kDirectional };

struct Light {
  LightKind kind = LightKind::kPoint;
  Vec3f position;        // area: centre; point: position
  Vec3f edge_u, edge_v;  // area: full edges; front face along normal
  Vec3f normal;          // area: normalize(edge_u x edge_v)
  float area = 0;        // area: mm^2
  Vec3f direction;       // directional: the direction light travels
  Vec3f emitted;         // area: radiance; point: radiant intensity; directional: irradiance
  std::int32_t two_sided = 0;
  std::int32_t visible = 0;  // area: seen by camera rays
};

// A piecewise-constant 2D distribution over the map's texels (pbrt's
// Distribution2D): rows by marginal CDF, columns by per-row conditional CDFs.
struct EnvironmentMapView {
  const Vec4f* texels = nullptr;         // width * height, rgb radiance (intensity applied)
  const float* marginal_cdf = nullptr;   // height + 1
  const float* conditional_cdf = nullptr;  // height * (width + 1)
  const float* weight = nullptr;         // width * height: luminance * sin(theta)
  float weight_integral = 0;             // mean of weight over the texels
  int width = 0, height = 0;
};

struct Environment {
  enum class Kind : std::int32_t { kNone, kUniform, kGradient, kMap };
  Kind kind = Kind::kNone;
  Vec3f zenith;   // uniform: the colour; gradient: towards up
  Vec3f horizon;  // gradient only
  Vec3f ground;   // gradient only: away from up
  Vec3f up{0, 0, 1};
  float rotation = 0;  // map: radians about +z
  std::int32_t visible = 1;  // seen by camera rays as the background
  EnvironmentMapView map;
};

// The host's description of a scene's lighting, from which backends build
// their views.
struct EnvironmentSetup {
  Environment::Kind kind = Environment::Kind::kNone;
  Vec3f zenith, horizon, ground;  // as in Environment, intensity applied
  Vec3f up{0, 0, 1};
  float rotation = 0;  // radians
  bool visible = true;  // as the background
  ImageRgbF map;       // kMap: equirectangular radiance, intensity applied
};

struct LightSetup {
  std::vector<Light> lights;
  EnvironmentSetup environment;
};

struct LightSample {
  Vec3f wi;        // towards the light
  float distance;  // to the sampled point; huge for distant lights
  Vec3f radiance;  // arriving at the shading point (intensity / d^2 for points)
  float pdf;       // solid angle; 1 for delta lights
  bool delta;      // point or directional: no MIS
};

inline constexpr float kInfiniteDistance = 1e30f;

CINEVOL_HD bool SampleLight(const Light& light, Vec3f p, float u1, float u2, LightSample& s) {
  if (light.kind == LightKind::kDirectional) {
    s = {-light.direction, kInfiniteDistance, light.emitted, 1.0f, true};
    return true;
  }
  const Vec3f target = light.kind == LightKind::kArea
                           ? light.position + light.edge_u * (u1 - 0.5f) + light.edge_v * (u2 - 0.5f)
                           : light.position;
  const Vec3f to = target - p;
  const float d2 = Dot(to, to);
  if (!(d2 > 0.0f)) return false;
  const float d = sqrtf(d2);
  const Vec3f wi = to / d;
  if (light.kind == LightKind::kPoint) {
    s = {wi, d, light.emitted / d2, 1.0f, true};
    return true;
  }
  const float cos_light = -Dot(wi, light.normal);
  if (cos_light <= 0.0f && !light.two_sided) return false;
  const float abs_cos = fabsf(cos_light);
  if (abs_cos < 1e-7f) return false;
  s = {wi, d, light.emitted, d2 / (light.area * abs_cos), false};
  return true;
}

// Where o + t d crosses an area light in (0, t_max): the radiance it emits
// towards o and the solid-angle pdf SampleLight would give that direction.
CINEVOL_HD bool IntersectAreaLight(const Light& light, Vec3f o, Vec3f d, float t_max, Vec3f& radiance,
                                   float& pdf) {
  const float denom = Dot(d, light.normal);
  if (fabsf(denom) < 1e-9f) return false;
  const float t = Dot(light.position - o, light.normal) / denom;
  if (!(t > 0.0f && t < t_max)) return false;
  const Vec3f local = o + d * t - light.position;
  const float su = Dot(local, light.edge_u) / Dot(light.edge_u, light.edge_u);
  const float sv = Dot(local, light.edge_v) / Dot(light.edge_v, light.edge_v);
  if (fabsf(su) > 0.5f || fabsf(sv) > 0.5f) return false;
  if (denom > 0.0f && !light.two_sided) return false;  // seen from behind
  radiance = light.emitted;
  pdf = t * t / (light.area * fabsf(denom));
  return true;
}

// Equirectangular mapping with +z up: u along azimuth, v from +z (0) to -z (1).
CINEVOL_HD void DirectionToMapUv(Vec3f d, float rotation, float& u, float& v) {
  float phi = atan2f(d.y, d.x) - rotation;
  phi -= 2.0f * kPi * floorf(phi / (2.0f * kPi));
  u = phi / (2.0f * kPi);
  v = acosf(Clamp(d.z, -1.0f, 1.0f)) * kInvPi;
}

CINEVOL_HD Vec3f MapUvToDirection(float u, float v, float rotation) {
  const float phi = u * 2.0f * kPi + rotation, theta = v * kPi;
  const float st = sinf(theta);
  return {st * cosf(phi), st * sinf(phi), cosf(theta)};
}

CINEVOL_HD int MapTexelIndex(const EnvironmentMapView& m, float u, float v) {
  // Clamped both ways: a direction that is not a number must still read a texel.
  const int x = MaxInt(0, MinInt(static_cast<int>(u * float(m.width)), m.width - 1));
  const int y = MaxInt(0, MinInt(static_cast<int>(v * float(m.height)), m.height - 1));
  return y * m.width + x;
}

// kWithMap = false compiles the map out (for scenes without one).
template <bool kWithMap = true>
CINEVOL_HD Vec3f EnvironmentRadiance(const Environment& env, Vec3f d) {
  if constexpr (!kWithMap) {
    if (env.kind == Environment::Kind::kUniform) return env.zenith;
    if (env.kind != Environment::Kind::kGradient) return {};
    const float c = Dot(d, env.up);
    return c >= 0.0f ? Lerp(env.horizon, env.zenith, c) : Lerp(env.horizon, env.ground, -c);
  }
  switch (env.kind) {
    case Environment::Kind::kUniform:
      return env.zenith;
    case Environment::Kind::kGradient: {
      const float c = Dot(d, env.up);
      return c >= 0.0f ? Lerp(env.horizon, env.zenith, c) : Lerp(env.horizon, env.ground, -c);
    }
    case Environment::Kind::kMap: {
      float u, v;
      DirectionToMapUv(d, env.rotation, u, v);
      return Xyz(LoadReadOnly(env.map.texels + MapTexelIndex(env.map, u, v)));
    }
    default:
      return {};
  }
}

// Finds i with cdf[i] <= u < cdf[i+1] in a CDF of n + 1 entries.
CINEVOL_HD int FindInterval(const float* cdf, int n, float u) {
  int lo = 0, hi = n;  // invariant: cdf[lo] <= u < cdf[hi] (cdf[n] = 1)
  while (hi - lo > 1) {
    const int mid = (lo + hi) / 2;
    if (LoadReadOnly(cdf + mid) <= u) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  return lo;
}

template <bool kWithMap = true>
CINEVOL_HD float EnvironmentPdf(const Environment& env, Vec3f d) {
  if (env.kind == Environment::Kind::kNone) return 0.0f;
  if (!kWithMap || env.kind != Environment::Kind::kMap) return UniformSpherePdf();
  float u, v;
  DirectionToMapUv(d, env.rotation, u, v);
  const float sin_theta = sinf(v * kPi);
  if (sin_theta <= 1e-6f || env.map.weight_integral <= 0.0f) return 0.0f;
  const float pdf_uv = LoadReadOnly(env.map.weight + MapTexelIndex(env.map, u, v)) / env.map.weight_integral;
  return pdf_uv / (2.0f * kPi * kPi * sin_theta);
}

// Uniform directions for analytic skies, the map's distribution otherwise.
template <bool kWithMap = true>
CINEVOL_HD bool SampleEnvironment(const Environment& env, float u1, float u2, LightSample& s) {
  if (env.kind == Environment::Kind::kNone) return false;
  Vec3f wi;
  if (!kWithMap || env.kind != Environment::Kind::kMap) {
    wi = SampleUniformSphere(u1, u2);
  } else {
    const EnvironmentMapView& m = env.map;
    const int row = FindInterval(m.marginal_cdf, m.height, u2);
    const float* cdf = m.conditional_cdf + row * (m.width + 1);
    const int col = FindInterval(cdf, m.width, u1);
    // Continuous position inside the chosen texel.
    const float r0 = LoadReadOnly(m.marginal_cdf + row), r1 = LoadReadOnly(m.marginal_cdf + row + 1);
    const float c0 = LoadReadOnly(cdf + col), c1 = LoadReadOnly(cdf + col + 1);
    const float dv = r1 > r0 ? (u2 - r0) / (r1 - r0) : 0.5f;
    const float du = c1 > c0 ? (u1 - c0) / (c1 - c0) : 0.5f;
    wi = MapUvToDirection((float(col) + du) / float(m.width), (float(row) + dv) / float(m.height), env.rotation);
  }
  const float pdf = EnvironmentPdf<kWithMap>(env, wi);
  if (!(pdf > 0.0f)) return false;
  s = {wi, kInfiniteDistance, EnvironmentRadiance<kWithMap>(env, wi), pdf, false};
  return true;
}

}  // namespace cinevol

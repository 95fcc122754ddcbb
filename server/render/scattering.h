// Scattering at a real collision (Exposure Render's hybrid scattering): a
// Henyey-Greenstein phase function, or a surface-like BRDF around the local
// gradient. The BRDF is Ashikhmin-Shirley's Fresnel blend: a diffuse term that
// loses what the specular lobe reflects, plus a GGX microfacet lobe with
// Schlick's Fresnel. Directions point away from the collision: wo towards the
// viewer, wi towards the light.
#pragma once

#include "core/sampling.h"
#include "core/vec.h"

namespace cinevol {

// The scattering function chosen at one collision.
struct Scatterer {
  bool surface;       // BRDF (true) or phase function
  Vec3f diffuse;      // BRDF diffuse reflectance, or the phase function's albedo
  Vec3f specular;     // BRDF only: reflectance at normal incidence
  float alpha;        // BRDF only: GGX width, roughness^2
  Vec3f normal;       // BRDF only: unit, on wo's side
  float g;            // phase only: anisotropy
};

// Exposure Render's P_brdf = opacity * (1 - exp(-25 g^3 |grad|)), with g the
// gradient factor and |grad| the normalised gradient magnitude.
CINEVOL_HD float SurfaceProbability(float opacity, float gradient_factor, float normalised_gradient) {
  const float g3 = gradient_factor * gradient_factor * gradient_factor;
  return Clamp(opacity * (1.0f - expf(-25.0f * g3 * normalised_gradient)), 0.0f, 1.0f);
}

CINEVOL_HD float Pow5(float x) {
  const float x2 = x * x;
  return x2 * x2 * x;
}

CINEVOL_HD float GgxD(float cos_h, float alpha) {
  const float a2 = alpha * alpha;
  const float d = cos_h * cos_h * (a2 - 1.0f) + 1.0f;
  return a2 / (kPi * d * d);
}

// Reflectance times |cos(theta_i)|: what multiplies incident radiance.
CINEVOL_HD Vec3f FresnelBlend(const Scatterer& s, Vec3f wo, Vec3f wi) {
  const float cos_o = Dot(wo, s.normal), cos_i = Dot(wi, s.normal);
  if (cos_o <= 0.0f || cos_i <= 0.0f) return {};
  const Vec3f one{1, 1, 1};
  const Vec3f diffuse = s.diffuse * (one - s.specular) *
                        (28.0f / (23.0f * kPi) * (1.0f - Pow5(1.0f - 0.5f * cos_i)) *
                         (1.0f - Pow5(1.0f - 0.5f * cos_o)));
  Vec3f h = wi + wo;
  if (Dot(h, h) == 0.0f) return diffuse * cos_i;
  h = Normalize(h);
  const float cos_ih = fmaxf(Dot(wi, h), 0.0f);
  const Vec3f fresnel = s.specular + (one - s.specular) * Pow5(1.0f - cos_ih);
  const float lobe = GgxD(Dot(h, s.normal), s.alpha) / (4.0f * fmaxf(cos_ih, 1e-6f) * fmaxf(cos_i, cos_o));
  return (diffuse + fresnel * lobe) * cos_i;
}

// Half cosine-weighted, half GGX-distributed half vectors.
CINEVOL_HD float FresnelBlendPdf(const Scatterer& s, Vec3f wo, Vec3f wi) {
  const float cos_o = Dot(wo, s.normal), cos_i = Dot(wi, s.normal);
  if (cos_o <= 0.0f || cos_i <= 0.0f) return 0.0f;
  const Vec3f h = Normalize(wi + wo);
  const float cos_h = Dot(h, s.normal);
  const float pdf_h = GgxD(cos_h, s.alpha) * cos_h;
  return 0.5f * (cos_i * kInvPi + pdf_h / (4.0f * fmaxf(Dot(wo, h), 1e-6f)));
}

CINEVOL_HD Vec3f SampleFresnelBlend(const Scatterer& s, Vec3f wo, float u0, float u1, float u2) {
  Vec3f t, b;
  OrthonormalBasis(s.normal, t, b);
  if (u0 < 0.5f) {
    const Vec3f l = SampleCosineHemisphere(u1, u2);
    return t * l.x + b * l.y + s.normal * l.z;
  }
  // GGX half vector: tan^2(theta) = alpha^2 u / (1 - u).
  const float tan2 = s.alpha * s.alpha * u1 / (1.0f - u1);
  const float cos_h = 1.0f / sqrtf(1.0f + tan2);
  const float sin_h = SafeSqrt(1.0f - cos_h * cos_h);
  float sin_phi, cos_phi;
  SinCosPi(2.0f * u2, sin_phi, cos_phi);
  const Vec3f h = t * (sin_h * cos_phi) + b * (sin_h * sin_phi) + s.normal * cos_h;
  return h * (2.0f * Dot(wo, h)) - wo;
}

// Value (f * |cos| for the BRDF, albedo * phase otherwise) and pdf of wi.
CINEVOL_HD Vec3f EvalScatter(const Scatterer& s, Vec3f wo, Vec3f wi, float& pdf) {
  if (s.surface) {
    pdf = FresnelBlendPdf(s, wo, wi);
    return FresnelBlend(s, wo, wi);
  }
  pdf = HenyeyGreenstein(Dot(wo, wi), s.g);
  return s.diffuse * pdf;
}

// Samples wi; returns value / pdf (the throughput factor), or zero.
CINEVOL_HD Vec3f SampleScatter(const Scatterer& s, Vec3f wo, float u0, float u1, float u2, Vec3f& wi,
                               float& pdf) {
  if (!s.surface) {
    wi = SampleHenyeyGreenstein(wo, s.g, u1, u2);
    pdf = HenyeyGreenstein(Dot(wo, wi), s.g);
    return s.diffuse;
  }
  wi = SampleFresnelBlend(s, wo, u0, u1, u2);
  const Vec3f f = EvalScatter(s, wo, wi, pdf);
  return pdf > 0.0f ? f / pdf : Vec3f{};
}

}  // namespace cinevol

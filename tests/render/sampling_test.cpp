// Every sampling routine against its pdf: histograms of sampled directions
// match the pdf integrated over each bin, and pdfs integrate to one.
#include <gtest/gtest.h>

#include <functional>

#include "core/camera.h"
#include "core/lights.h"
#include "core/rng.h"
#include "core/sampling.h"
#include "render/scattering.h"
#include "render/scene_data.h"

namespace cinevol {
namespace {

using Sampler = std::function<bool(Pcg32&, Vec3f&)>;  // false: no sample (counted as lost)
using Pdf = std::function<float(Vec3f)>;

Vec3f Spherical(float theta, float phi) {
  return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

// Bins directions in (theta, phi) and compares counts with N * the pdf's
// integral over each bin (midpoint rule on a sub-grid). Returns the pdf's
// integral over the sphere.
double ExpectHistogramMatchesPdf(const Sampler& sample, const Pdf& pdf, int n_theta, int n_phi,
                                 int samples = 400000, int sub = 12) {
  std::vector<double> counts(std::size_t(n_theta) * n_phi, 0.0);
  Pcg32 rng(42, 7);
  for (int i = 0; i < samples; ++i) {
    Vec3f d;
    if (!sample(rng, d)) continue;
    const float theta = std::acos(std::clamp(d.z, -1.0f, 1.0f));
    float phi = std::atan2(d.y, d.x);
    if (phi < 0) phi += 2 * kPi;
    const int bt = std::min(int(theta / kPi * n_theta), n_theta - 1);
    const int bp = std::min(int(phi / (2 * kPi) * n_phi), n_phi - 1);
    counts[bt * n_phi + bp] += 1;
  }
  double total = 0;
  for (int bt = 0; bt < n_theta; ++bt) {
    for (int bp = 0; bp < n_phi; ++bp) {
      double integral = 0;
      const double dt = kPi / n_theta / sub, dp = 2 * kPi / n_phi / sub;
      for (int i = 0; i < sub; ++i) {
        for (int j = 0; j < sub; ++j) {
          const double theta = (bt * sub + i + 0.5) * dt, phi = (bp * sub + j + 0.5) * dp;
          integral += pdf(Spherical(float(theta), float(phi))) * std::sin(theta) * dt * dp;
        }
      }
      total += integral;
      const double expected = integral * samples, observed = counts[bt * n_phi + bp];
      EXPECT_NEAR(observed, expected, 5 * std::sqrt(expected) + 0.03 * expected + 3)
          << "bin theta " << bt << " phi " << bp;
    }
  }
  return total;
}

TEST(Sampling, UniformSphere) {
  const double integral = ExpectHistogramMatchesPdf(
      [](Pcg32& r, Vec3f& d) { d = SampleUniformSphere(r.Uniform(), r.Uniform()); return true; },
      [](Vec3f) { return UniformSpherePdf(); }, 16, 32);
  EXPECT_NEAR(integral, 1.0, 1e-3);
}

TEST(Sampling, CosineHemisphere) {
  const double integral = ExpectHistogramMatchesPdf(
      [](Pcg32& r, Vec3f& d) { d = SampleCosineHemisphere(r.Uniform(), r.Uniform()); return true; },
      [](Vec3f d) { return CosineHemispherePdf(d.z); }, 16, 32);
  EXPECT_NEAR(integral, 1.0, 1e-3);
}

TEST(Sampling, HenyeyGreenstein) {
  const Vec3f wo = Normalize(Vec3f{0.3f, -0.5f, 0.8f});
  for (float g : {-0.7f, 0.0f, 0.3f, 0.8f}) {
    SCOPED_TRACE(g);
    const double integral = ExpectHistogramMatchesPdf(
        [&](Pcg32& r, Vec3f& d) { d = SampleHenyeyGreenstein(wo, g, r.Uniform(), r.Uniform()); return true; },
        [&](Vec3f d) { return HenyeyGreenstein(Dot(wo, d), g); }, 24, 48);
    EXPECT_NEAR(integral, 1.0, 5e-3);
  }
}

TEST(Sampling, HenyeyGreensteinScattersForwardForPositiveG) {
  // Light arrives travelling along -wi and leaves along wo; forward scattering
  // keeps its direction, so wo is near -wi and the mean of Dot(wo, wi) is -g.
  const Vec3f wo{0, 0, 1};
  Pcg32 rng(1, 1);
  double mean_cos = 0;
  for (int i = 0; i < 20000; ++i)
    mean_cos += Dot(wo, SampleHenyeyGreenstein(wo, 0.8f, rng.Uniform(), rng.Uniform())) / 20000;
  EXPECT_NEAR(mean_cos, -0.8, 0.02);  // the mean cosine of HG is g (about the travel direction)
}

TEST(Sampling, FresnelBlendBrdf) {
  for (float alpha : {0.1f, 0.4f, 1.0f}) {
    SCOPED_TRACE(alpha);
    Scatterer s{true, {0.8f, 0.8f, 0.8f}, {0.3f, 0.3f, 0.3f}, alpha, {0, 0, 1}, 0.0f};
    const Vec3f wo = Normalize(Vec3f{0.5f, 0.1f, 0.7f});
    const double integral = ExpectHistogramMatchesPdf(
        [&](Pcg32& r, Vec3f& d) {
          d = SampleFresnelBlend(s, wo, r.Uniform(), r.Uniform(), r.Uniform());
          return FresnelBlendPdf(s, wo, d) > 0.0f;  // below the surface: lost
        },
        [&](Vec3f d) { return FresnelBlendPdf(s, wo, d); }, 32, 64, 400000, 16);
    EXPECT_LE(integral, 1.0 + 1e-2);
    EXPECT_GT(integral, 0.75);
  }
}

TEST(Sampling, FresnelBlendReflectsNoMoreThanItReceives) {
  // White-furnace check of the BRDF: the directional albedo stays <= 1.
  Scatterer s{true, {1, 1, 1}, {1, 1, 1}, 0.3f, {0, 0, 1}, 0.0f};
  Pcg32 rng(5, 5);
  for (float cos_o : {0.1f, 0.5f, 1.0f}) {
    const Vec3f wo{std::sqrt(1 - cos_o * cos_o), 0, cos_o};
    double albedo = 0;
    const int n = 200000;
    for (int i = 0; i < n; ++i) {
      Vec3f wi;
      float pdf;
      albedo += MaxComponent(SampleScatter(s, wo, rng.Uniform(), rng.Uniform(), rng.Uniform(), wi, pdf)) / n;
    }
    EXPECT_LE(albedo, 1.02) << "cos_o " << cos_o;
  }
}

TEST(Sampling, EnvironmentMapImportance) {
  ImageRgbF map{16, 8, std::vector<Vec3f>(16 * 8, Vec3f{0.1f, 0.1f, 0.1f})};
  map.pixels[3 * 16 + 5] = {50, 40, 30};  // a sun
  map.pixels[6 * 16 + 12] = {0, 0, 0};
  const EnvironmentDistribution dist = BuildEnvironmentDistribution(map);
  Environment env;
  env.kind = Environment::Kind::kMap;
  env.rotation = 0.0f;
  env.map = {dist.texels.data(), dist.marginal_cdf.data(), dist.conditional_cdf.data(), dist.weight.data(),
             dist.weight_integral, 16, 8};
  // Bins aligned with the texels: the pdf is constant on each.
  const double integral = ExpectHistogramMatchesPdf(
      [&](Pcg32& r, Vec3f& d) {
        LightSample s;
        if (!SampleEnvironment(env, r.Uniform(), r.Uniform(), s)) return false;
        d = s.wi;
        return true;
      },
      [&](Vec3f d) { return EnvironmentPdf(env, d); }, 8, 16);
  EXPECT_NEAR(integral, 1.0, 1e-3);
}

// Solid angle of a parallelogram seen from p (two triangles, Van Oosterom and Strackee).
double TriangleSolidAngle(Vec3f a, Vec3f b, Vec3f c) {
  const double la = Length(a), lb = Length(b), lc = Length(c);
  const double num = Dot(a, Cross(b, c));
  const double den = la * lb * lc + Dot(a, b) * lc + Dot(a, c) * lb + Dot(b, c) * la;
  return std::abs(2.0 * std::atan2(num, den));
}

TEST(Sampling, AreaLightPdfMatchesItsSolidAngleAndIntersection) {
  Light l;
  l.kind = LightKind::kArea;
  l.position = {10, 20, 30};
  l.edge_u = {8, 0, 2};
  l.edge_v = {0, 5, 0};
  const Vec3f n = Cross(l.edge_u, l.edge_v);
  l.area = Length(n);
  l.normal = n / l.area;
  l.two_sided = 1;
  l.emitted = {1, 1, 1};
  const Vec3f p{0, 0, 0};
  Pcg32 rng(3, 3);
  double inv_pdf_sum = 0;
  const int n_samples = 100000;
  for (int i = 0; i < n_samples; ++i) {
    LightSample s;
    ASSERT_TRUE(SampleLight(l, p, rng.Uniform(), rng.Uniform(), s));
    inv_pdf_sum += 1.0 / s.pdf;
    Vec3f radiance;
    float pdf;
    ASSERT_TRUE(IntersectAreaLight(l, p, s.wi, 1e9f, radiance, pdf));
    ASSERT_NEAR(pdf, s.pdf, 1e-3f * s.pdf);
  }
  const Vec3f c00 = l.position - l.edge_u * 0.5f - l.edge_v * 0.5f, c10 = c00 + l.edge_u,
              c11 = c10 + l.edge_v, c01 = c00 + l.edge_v;
  const double omega = TriangleSolidAngle(c00 - p, c10 - p, c11 - p) + TriangleSolidAngle(c00 - p, c11 - p, c01 - p);
  EXPECT_NEAR(inv_pdf_sum / n_samples, omega, 0.01 * omega);
}

TEST(Sampling, OneSidedAreaLightIsDarkBehind) {
  Light l;
  l.kind = LightKind::kArea;
  l.position = {0, 0, 10};
  l.edge_u = {2, 0, 0};
  l.edge_v = {0, 2, 0};
  l.normal = {0, 0, 1};  // faces +z, away from the origin
  l.area = 4;
  l.emitted = {1, 1, 1};
  LightSample s;
  EXPECT_FALSE(SampleLight(l, {0, 0, 0}, 0.5f, 0.5f, s));
  Vec3f radiance;
  float pdf;
  EXPECT_FALSE(IntersectAreaLight(l, {0, 0, 0}, {0, 0, 1}, 1e9f, radiance, pdf));
  EXPECT_TRUE(IntersectAreaLight(l, {0, 0, 20}, {0, 0, -1}, 1e9f, radiance, pdf));
}

TEST(Sampling, TruncatedGaussianPixelFilter) {
  const float sigma = 0.5f, radius = 1.5f;
  const int bins = 30, n = 300000;
  std::vector<double> counts(bins);
  Pcg32 rng(9, 9);
  for (int i = 0; i < n; ++i) {
    const float x = SampleTruncatedGaussian(rng.Uniform(), sigma, radius);
    ASSERT_LE(std::abs(x), radius + 1e-4f);
    counts[std::min(int((x + radius) / (2 * radius) * bins), bins - 1)] += 1;
  }
  const double norm = std::erf(radius / (sigma * std::sqrt(2.0)));
  for (int b = 0; b < bins; ++b) {
    const double lo = -radius + 2.0 * radius * b / bins, hi = lo + 2.0 * radius / bins;
    const double p = 0.5 * (std::erf(hi / (sigma * std::sqrt(2.0))) - std::erf(lo / (sigma * std::sqrt(2.0)))) / norm;
    EXPECT_NEAR(counts[b], p * n, 5 * std::sqrt(p * n) + 2) << "bin " << b;
  }
}

TEST(Camera, ProjectInvertsGenerateRay) {
  const Camera c = LookAt({100, -300, 50}, {0, 0, 0}, {0, 0, 1}, 35, 640, 480);
  for (float px : {0.5f, 100.25f, 639.5f}) {
    for (float py : {0.5f, 240.0f, 479.5f}) {
      const Ray r = c.GenerateRay(px, py, 0.5f, 0.5f);
      float qx, qy;
      ASSERT_TRUE(c.Project(r.origin + r.direction * 123.0f, qx, qy));
      EXPECT_NEAR(qx, px, 1e-2f);
      EXPECT_NEAR(qy, py, 1e-2f);
    }
  }
}

TEST(Camera, ThinLensFocusesOnItsFocalPlane) {
  Camera c = LookAt({0, -500, 0}, {0, 0, 0}, {0, 0, 1}, 30, 64, 48);
  c.lens_radius = 20.0f;
  c.focal_distance = 400.0f;
  Pcg32 rng(2, 2);
  const Ray pinhole = c.GenerateRay(10.5f, 30.5f, 0.5f, 0.5f);  // the lens centre
  const Vec3f focus = pinhole.origin + pinhole.direction * (c.focal_distance / Dot(pinhole.direction, c.forward));
  for (int i = 0; i < 100; ++i) {
    const Ray r = c.GenerateRay(10.5f, 30.5f, rng.Uniform(), rng.Uniform());
    EXPECT_LE(Length(r.origin - c.eye), c.lens_radius + 1e-3f);
    const float t = Dot(focus - r.origin, c.forward) / Dot(r.direction, c.forward);
    EXPECT_LT(Length(r.origin + r.direction * t - focus), 1e-2f);  // every lens sample meets there
  }
}

}  // namespace
}  // namespace cinevol

// The volumetric path tracer: one function per pixel, shared by the CPU and
// CUDA backends. Free paths by delta tracking against the majorant grid,
// shadow rays by ratio tracking, next-event estimation combined with
// phase/BRDF sampling by multiple importance sampling (power heuristic),
// hybrid scattering, transfer-function emission and Russian roulette.
//
// Bounces count scattering events: max_bounces = 0 shows emission and the
// lights seen directly through the volume; 1 is single scattering.
//
// What one path costs is bounded: at most kMaxPathCollisions tentative
// collisions (volume lookups) over all its free flights and shadow rays, plus
// one DDA step per brick each of its at most 2 * max_bounces + 1 tracking
// calls crosses (docs/rendering.md, "Values at the extremes").
#pragma once

#include "core/rng.h"
#include "render/classification.h"
#include "render/render_scene.h"
#include "render/sample_pattern.h"
#include "render/scattering.h"

namespace cinevol {

// Gaussian pixel filter: standard deviation and truncation radius, in pixels.
inline constexpr float kPixelFilterSigma = 0.5f;
inline constexpr float kPixelFilterRadius = 1.5f;
// Russian roulette starts after this many scattering events.
inline constexpr int kRouletteDepth = 3;

struct PathResult {
  Vec3f radiance;
  Vec3f first_hit;        // first real collision, when hit
  Vec3f albedo{1, 1, 1};  // diffuse colour there; 1 for escaped paths (demodulation)
  bool hit = false;
};

template <unsigned kFeatures>
class PathTracer {
 public:
  static constexpr bool kWithGradients = kFeatures & kGradients;
  static constexpr bool kWithEmission = kFeatures & kEmission;
  static constexpr bool kWithMap = kFeatures & kEnvironmentMap;
  static constexpr bool kMultiple = kFeatures & kMultipleScattering;
  static constexpr bool kChooseLight = kFeatures & kSeveralLights;
  static constexpr bool kCubic = kFeatures & kTricubic;
  static constexpr bool kWithLabels = kFeatures & kLabels;
  static constexpr bool kWithFusion = kFeatures & kFusion;
  static constexpr bool kTextureOnly = ReadsTexturesOnly(kFeatures);

  CINEVOL_HD PathTracer(const RenderScene& scene, Pcg32& rng) : s_(scene), rng_(rng) {}

  // Tentative collisions the paths traced so far took from the budget
  // (kMaxPathCollisions per path), and how many of those paths it ended.
  CINEVOL_HD int collisions() const { return collisions_; }
  CINEVOL_HD int budget_ends() const { return budget_ends_; }

  CINEVOL_HD PathResult Trace(Ray ray) {
    PathResult result;
    Vec3f beta{1, 1, 1};
    float scatter_pdf = 0.0f;  // pdf of the direction `ray` was sampled with
    budget_ = kMaxPathCollisions;
    const int max_bounces = kMultiple ? s_.max_bounces : MinInt(s_.max_bounces, 1);
    for (int depth = 0;; ++depth) {
      float t_hit = 0.0f;
      Classified hit;
      const Collision c = NextCollision(ray, t_hit, hit);
      if (c == Collision::kAbsorbedByBudget) {
        ++budget_ends_;
        break;
      }
      const bool from_camera = depth == 0;
      result.radiance +=
          beta * CrossedLights(ray, c == Collision::kHit ? t_hit : kInfiniteDistance, scatter_pdf, from_camera);
      if (c == Collision::kEscaped) {
        result.radiance += beta * EscapedRadiance(ray.direction, scatter_pdf, from_camera);
        break;
      }
      const Vec3f p = ray.origin + ray.direction * t_hit;
      const Material m = MaterialOf(hit);
      if (from_camera) {
        result.first_hit = p;
        result.albedo = m.diffuse;
        result.hit = true;
      }
      if constexpr (kWithEmission) result.radiance += beta * EmissionOf<kWithLabels, kWithFusion>(s_, hit);
      if (depth >= max_bounces) break;

      const Vec3f wo = -ray.direction;
      const Scatterer sc = MakeScatterer(p, wo, m, hit.fused);
      result.radiance += beta * DirectLight(p, wo, sc);
      // The last scattering event only matters through what its sampled ray
      // can reach: hittable lights or an emitting volume.
      if (depth + 1 >= max_bounces && !s_.has_hittable_lights && !kWithEmission) break;

      const float u0 = rng_.Uniform(), u1 = rng_.Uniform(), u2 = rng_.Uniform();
      Vec3f wi;
      const Vec3f weight = SampleScatter(sc, wo, u0, u1, u2, wi, scatter_pdf);
      if (!(scatter_pdf > 0.0f) || !(MaxComponent(weight) > 0.0f)) break;
      beta *= weight;
      ray = {p, wi};
      if constexpr (kMultiple) {
        // Terminate with probability 1 - max(beta) (as pbrt does): survivors
        // return to a throughput near 1, so weights never grow without bound.
        if (depth + 1 >= kRouletteDepth) {
          const float q = fmaxf(0.0f, 1.0f - MaxComponent(beta));
          if (rng_.Uniform() < q) break;
          beta *= 1.0f / (1.0f - q);
        }
      }
    }
    collisions_ += kMaxPathCollisions - MaxInt(budget_, 0);
    return result;
  }

 private:
  enum class Collision { kHit, kEscaped, kAbsorbedByBudget };

  CINEVOL_HD float Extinction(Vec3f p, Classified& c) const {
    return ExtinctionAt<kCubic, kWithLabels, kWithFusion, kTextureOnly>(s_, p, c);
  }
  CINEVOL_HD Material MaterialOf(const Classified& c) const {
    return cinevol::MaterialOf<kWithLabels, kWithFusion>(s_, c);
  }

  // Delta tracking to the next real collision along the ray. A ray that
  // enters the kept region through a capped face meets the cut tissue there
  // as a surface, with the tissue's opacity as the probability.
  CINEVOL_HD Collision NextCollision(const Ray& ray, float& t_hit, Classified& hit) {
    float t0, t1;
    int entered;
    const Vec3f inv{1.0f / ray.direction.x, 1.0f / ray.direction.y, 1.0f / ray.direction.z};
    if (!IntersectBox(ray.origin, inv, s_.volume.box_min, s_.volume.box_max, t0, t1) ||
        !s_.clip.Clip(ray.origin, ray.direction, t0, t1, &entered)) {
      return Collision::kEscaped;
    }
    cap_ = false;
    if (entered >= 0 && (s_.clip.capped >> entered & 1u)) {
      Extinction(ray.origin + ray.direction * t0, hit);
      if (rng_.Uniform() < MaterialOf(hit).opacity) {
        t_hit = t0;
        cap_ = true;
        cap_normal_ = -Xyz(s_.clip.half_spaces[entered]);  // out of the kept region, towards the ray
        return Collision::kHit;
      }
    }
    bool found = false;
    const TrackResult r = SampleMajorant(
        s_.majorants, ray.origin, ray.direction, t0, t1, rng_, budget_, [&](float t, float inv_majorant) {
          Classified c;
          if (rng_.Uniform() >= Extinction(ray.origin + ray.direction * t, c) * inv_majorant) return true;
          t_hit = t;
          hit = c;
          // Which of two mixed media the collision met, by their shares.
          if constexpr (kWithFusion) hit.fused = rng_.Uniform() < c.fused_share;
          found = true;
          return false;
        });
    if (r == TrackResult::kBudgetExhausted) return Collision::kAbsorbedByBudget;
    return found ? Collision::kHit : Collision::kEscaped;
  }

  // Ratio tracking with Russian roulette on small transmittance.
  CINEVOL_HD float Transmittance(Vec3f p, Vec3f w, float distance) {
    float t0, t1;
    const Vec3f inv{1.0f / w.x, 1.0f / w.y, 1.0f / w.z};
    if (!IntersectBox(p, inv, s_.volume.box_min, s_.volume.box_max, t0, t1) || !s_.clip.Clip(p, w, t0, t1)) return 1.0f;
    t1 = fminf(t1, distance);
    if (!(t0 < t1)) return 1.0f;
    float transmittance = 1.0f;
    const TrackResult r = SampleMajorant(s_.majorants, p, w, t0, t1, rng_, budget_, [&](float t, float inv_majorant) {
      Classified c;
      transmittance *= fmaxf(0.0f, 1.0f - Extinction(p + w * t, c) * inv_majorant);
      if (transmittance < 0.05f) {
        if (rng_.Uniform() < 0.75f) {
          transmittance = 0.0f;
          return false;
        }
        transmittance *= 4.0f;
      }
      return true;
    });
    return r == TrackResult::kBudgetExhausted ? 0.0f : transmittance;
  }

  CINEVOL_HD int SampleableLights() const {
    return s_.light_count + (s_.environment.kind != Environment::Kind::kNone ? 1 : 0);
  }

  CINEVOL_HD float LightSelectionPdf() const { return kChooseLight ? 1.0f / float(SampleableLights()) : 1.0f; }

  // Hybrid scattering: the BRDF with Exposure Render's probability, else the
  // phase function. A second volume's medium scatters by its phase function alone.
  CINEVOL_HD Scatterer MakeScatterer(Vec3f p, Vec3f wo, const Material& m, bool fused) {
    if (cap_) return {true, m.diffuse, m.specular, fmaxf(m.roughness * m.roughness, 1e-3f), cap_normal_, 0.0f};
    if (kWithFusion && fused) return {false, m.diffuse, {}, 0.0f, {}, s_.fused.transfer.phase_g};
    Scatterer sc{false, m.diffuse, {}, 0.0f, {}, s_.transfer.phase_g};
    if constexpr (kWithGradients) {
      const Vec3f grad = s_.volume.template Gradient<kCubic, kTextureOnly>(p);
      const float magnitude = Length(grad);
      const float p_surface =
          SurfaceProbability(m.opacity, s_.transfer.gradient_factor, magnitude * s_.transfer.gradient_normaliser);
      if (magnitude > 0.0f && rng_.Uniform() < p_surface) {
        sc.surface = true;
        sc.normal = grad / magnitude;
        if (Dot(sc.normal, wo) < 0.0f) sc.normal = -sc.normal;
        sc.specular = m.specular;
        sc.alpha = fmaxf(m.roughness * m.roughness, 1e-3f);
      }
    }
    return sc;
  }

  // Next-event estimation towards one light.
  CINEVOL_HD Vec3f DirectLight(Vec3f p, Vec3f wo, const Scatterer& sc) {
    const int n = SampleableLights();
    if (n == 0) return {};
    const int i = kChooseLight ? MinInt(static_cast<int>(rng_.Uniform() * float(n)), n - 1) : 0;
    const float u1 = rng_.Uniform(), u2 = rng_.Uniform();
    LightSample ls;
    const bool sampled = i < s_.light_count ? SampleLight(s_.lights[i], p, u1, u2, ls)
                                            : SampleEnvironment<kWithMap>(s_.environment, u1, u2, ls);
    if (!sampled) return {};
    float scatter_pdf;
    const Vec3f f = EvalScatter(sc, wo, ls.wi, scatter_pdf);
    if (!(MaxComponent(f) > 0.0f) || !(MaxComponent(ls.radiance) > 0.0f)) return {};
    const float tr = Transmittance(p, ls.wi, ls.distance);
    if (tr <= 0.0f) return {};
    const float light_pdf = LightSelectionPdf() * ls.pdf;
    const float mis = ls.delta ? 1.0f : PowerHeuristic(light_pdf, scatter_pdf);
    return f * ls.radiance * (tr * mis / light_pdf);
  }

  // Area lights the ray crosses before t_max, weighted against NEE.
  CINEVOL_HD Vec3f CrossedLights(const Ray& ray, float t_max, float scatter_pdf, bool from_camera) const {
    Vec3f sum{};
    for (int i = 0; i < s_.light_count; ++i) {
      const Light& light = s_.lights[i];
      if (light.kind != LightKind::kArea || (from_camera && !light.visible)) continue;
      Vec3f radiance;
      float light_pdf;
      if (!IntersectAreaLight(light, ray.origin, ray.direction, t_max, radiance, light_pdf)) continue;
      sum += radiance * (from_camera ? 1.0f : PowerHeuristic(scatter_pdf, LightSelectionPdf() * light_pdf));
    }
    return sum;
  }

  CINEVOL_HD Vec3f EscapedRadiance(Vec3f d, float scatter_pdf, bool from_camera) const {
    if (s_.environment.kind == Environment::Kind::kNone || (from_camera && !s_.environment.visible)) return {};
    const Vec3f radiance = EnvironmentRadiance<kWithMap>(s_.environment, d);
    if (from_camera) return radiance;
    return radiance * PowerHeuristic(scatter_pdf, LightSelectionPdf() * EnvironmentPdf<kWithMap>(s_.environment, d));
  }

  const RenderScene& s_;
  Pcg32& rng_;
  bool cap_ = false;  // the last collision is on a capped face, with this normal (on the ray's side)
  Vec3f cap_normal_{};
  int budget_ = kMaxPathCollisions;  // tentative collisions left to the path being traced
  int collisions_ = 0, budget_ends_ = 0;
};

// The k-th of pixel (x, y)'s samples this frame: its paths are stratified
// per frame and seeded by (seed, frame, pixel, k), so the image depends on
// neither thread nor block order nor which thread traced which sample.
template <unsigned kFeatures>
CINEVOL_HD PathResult TracePixelSample(const RenderScene& s, int x, int y, int k) {
  const int pixel = y * s.camera.width + x;
  const std::uint64_t key = HashCombine(HashCombine(s.seed, s.frame), std::uint64_t(pixel));
  const std::uint32_t pattern = static_cast<std::uint32_t>(key);
  float fx, fy, lx, ly;
  CorrelatedMultiJitter(k, s.spp, pattern, fx, fy);
  CorrelatedMultiJitter(k, s.spp, pattern ^ 0x5bd1e995U, lx, ly);
  const float px = float(x) + 0.5f + SampleTruncatedGaussian(fx, kPixelFilterSigma, kPixelFilterRadius);
  const float py = float(y) + 0.5f + SampleTruncatedGaussian(fy, kPixelFilterSigma, kPixelFilterRadius);
  Pcg32 rng(key, std::uint64_t(k));
  PathTracer<kFeatures> tracer(s, rng);
  return tracer.Trace(s.camera.GenerateRay(px, py, lx, ly));
}

// A pixel's samples, added in sample order, and what the frame's targets get.
struct PixelSamples {
  Vec3f sum{}, albedo{};
  Vec4f first_hit{};
  float nearest = kInfiniteDistance;

  CINEVOL_HD void Add(const PathResult& r, Vec3f eye) {
    // A non-finite sample would poison the accumulation and the denoiser's
    // history; the integrator is built not to make one, this is the backstop.
    if (IsFinite(r.radiance)) sum += r.radiance;
    albedo += r.albedo;
    if (r.hit) {
      const float d = Length(r.first_hit - eye);
      if (d < nearest) {
        nearest = d;
        first_hit = ToVec4(r.first_hit, 1.0f);
      }
    }
  }

  // Samples another lane traced (cuda_renderer.cu), added after this one's;
  // a tie for the nearest hit goes to this one.
  CINEVOL_HD void Merge(const PixelSamples& later) {
    sum += later.sum;
    albedo += later.albedo;
    if (later.nearest < nearest) {
      nearest = later.nearest;
      first_hit = later.first_hit;
    }
  }

  CINEVOL_HD void Write(const FrameTargets& out, int pixel, int spp) const {
    out.radiance[pixel] = sum / float(spp);
    out.first_hit[pixel] = first_hit;
    out.albedo[pixel] = albedo / float(spp);
    // The samples' sum, not their mean: a frame weighs by its samples, so frames
    // of different spp (a CPU session's still frames, a still's growing chunks)
    // accumulate the plain mean of every sample (the renderers divide by them).
    if (out.accumulation_starts) {
      out.accumulated[pixel] = sum;
    } else {
      out.accumulated[pixel] += sum;
    }
  }
};

// FrameTargets::surface_normal for a pixel whose nearest first hit is
// `first_hit`: read once a pixel after its samples, so the paths carry
// nothing more.
template <unsigned kFeatures>
CINEVOL_HD Vec3f SurfaceNormalAt(const RenderScene& s, Vec4f first_hit) {
  if constexpr ((kFeatures & kGradients) == 0) {
    return {};
  } else {
    if (first_hit.w == 0.0f) return {};
    constexpr bool kCubic = kFeatures & kTricubic, kWithLabels = kFeatures & kLabels;
    constexpr bool kTextureOnly = ReadsTexturesOnly(kFeatures);
    const Vec3f p = Xyz(first_hit);
    Classified c;
    ExtinctionAt<kCubic, kWithLabels, false, kTextureOnly>(s, p, c);
    const Vec3f grad = s.volume.template Gradient<kCubic, kTextureOnly>(p);
    const float magnitude = Length(grad);
    if (!(magnitude > 0.0f)) return {};
    const float opacity = MaterialOf<kWithLabels>(s, c).opacity;
    const float p_surface =
        SurfaceProbability(opacity, s.transfer.gradient_factor, magnitude * s.transfer.gradient_normaliser);
    const Vec3f n = grad * (p_surface / magnitude);
    return Dot(n, s.camera.eye - p) < 0.0f ? -n : n;
  }
}

// Renders pixel (x, y): its spp samples, one after the other.
template <unsigned kFeatures>
CINEVOL_HD void RenderPixel(const RenderScene& s, int x, int y, const FrameTargets& out) {
  PixelSamples samples;
  for (int k = 0; k < s.spp; ++k) samples.Add(TracePixelSample<kFeatures>(s, x, y, k), s.camera.eye);
  const int pixel = y * s.camera.width + x;
  samples.Write(out, pixel, s.spp);
  if (out.surface_normal) out.surface_normal[pixel] = SurfaceNormalAt<kFeatures>(s, samples.first_hit);
}

}  // namespace cinevol

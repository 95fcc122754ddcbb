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
  Vec3f first_hit;         // first real collision, when hit
  Vec3f albedo{1, 1, 1};   // diffuse colour there; 1 for escaped paths (demodulation)
  bool hit = false;
};

// One path as a resumable machine. Start() sets it on a camera ray; each
// Advance() takes one step of the tracking in progress (one brick of the DDA
// or one tentative collision, for a free flight and a shadow ray alike) and
// then handles the event that ended a tracking, if one did: shading at a real
// collision, light crossed or escaped, the shadow ray's transmittance.
//
// Why a machine: on a GPU the 32 lanes of a warp run one instruction stream.
// Traced as nested loops, a lane in a shadow ray, one in a free flight and one
// whose path had ended each waited for the others (4.7 of 32 lanes active on
// the dense crop, docs/performance.md). Here every lane runs the same step
// code, whatever its path is doing, and a lane whose path ends takes a new one
// (render/cuda_renderer.cu). The CPU runs each path to its end (Trace).
//
// At a real collision the next direction is sampled before the shadow ray of
// next-event estimation is traced, so that only the pending contribution, not
// the scattering function, is kept while the shadow ray runs.
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

  CINEVOL_HD explicit PathTracer(const RenderScene& scene) : s_(scene) {}

  // Tentative collisions the paths traced so far took from the budget
  // (kMaxPathCollisions per path), and how many of those paths it ended.
  CINEVOL_HD int collisions() const { return collisions_; }
  CINEVOL_HD int budget_ends() const { return budget_ends_; }

  // A new path along `ray` drawing from `rng`.
  CINEVOL_HD void Start(Ray ray, Pcg32 rng) {
    rng_ = rng;
    result_ = PathResult{};
    beta_ = {1, 1, 1};
    scatter_pdf_ = 0.0f;
    depth_ = 0;
    budget_ = kMaxPathCollisions;
    StartFlight(ray);
  }

  CINEVOL_HD bool done() const { return phase_ == Phase::kDone; }
  CINEVOL_HD const PathResult& result() const { return result_; }

  // One step of the path; call until done().
  CINEVOL_HD void Advance() {
    if (phase_ == Phase::kTracking) TrackStep();
    if (phase_ == Phase::kFlightEnded) {
      OnFlightEnded();
    } else if (phase_ == Phase::kShadowEnded) {
      OnShadowEnded();
    }
  }

  // The whole path at once (the CPU backend, tests).
  CINEVOL_HD PathResult Trace(Ray ray, Pcg32 rng) {
    Start(ray, rng);
    while (!done()) Advance();
    return result_;
  }

 private:
  enum class Phase : unsigned char {
    kTracking,     // a free flight or a shadow ray is under way (shadow_ says which)
    kFlightEnded,  // the flight met a real collision, escaped or spent the budget (outcome_)
    kShadowEnded,  // transmittance_ is the shadow ray's
    kDone,
  };
  enum class Outcome : unsigned char { kHit, kEscaped, kAbsorbedByBudget };

  CINEVOL_HD float Extinction(Vec3f p, Classified& c) const { return ExtinctionAt<kCubic, kWithLabels>(s_, p, c); }
  CINEVOL_HD Material MaterialOf(const Classified& c) const { return cinevol::MaterialOf<kWithLabels>(s_, c); }

  CINEVOL_HD void EndFlight(Outcome outcome) {
    outcome_ = outcome;
    phase_ = Phase::kFlightEnded;
  }

  CINEVOL_HD void Finish() {
    collisions_ += kMaxPathCollisions - MaxInt(budget_, 0);
    phase_ = Phase::kDone;
  }

  // Delta tracking along `ray` to its next real collision. A ray that enters
  // the kept region through a capped face meets the cut tissue there as a
  // surface, with the tissue's opacity as the probability.
  CINEVOL_HD void StartFlight(Ray ray) {
    ray_ = ray;
    shadow_ = false;
    cap_face_ = -1;
    float t0, t1;
    int entered;
    if (!IntersectBox(ray.origin, Inverse(ray.direction), s_.volume.box_min, s_.volume.box_max, t0, t1) ||
        !s_.clip.Clip(ray.origin, ray.direction, t0, t1, &entered)) {
      return EndFlight(Outcome::kEscaped);
    }
    if (entered >= 0 && (s_.clip.capped >> entered & 1u)) {
      Extinction(ray.origin + ray.direction * t0, hit_);
      if (rng_.Uniform() < MaterialOf(hit_).opacity) {
        t_hit_ = t0;
        cap_face_ = entered;
        return EndFlight(Outcome::kHit);
      }
    }
    StartTracking(t0, t1);
  }

  // Ratio tracking towards a light, with Russian roulette on small
  // transmittance; `pending_` waits for its result.
  CINEVOL_HD void StartShadow(Vec3f p, Vec3f w, float distance) {
    ray_ = {p, w};
    shadow_ = true;
    transmittance_ = 1.0f;
    float t0, t1;
    if (!IntersectBox(p, Inverse(w), s_.volume.box_min, s_.volume.box_max, t0, t1) || !s_.clip.Clip(p, w, t0, t1) ||
        !(t0 < (t1 = fminf(t1, distance)))) {
      phase_ = Phase::kShadowEnded;
      return;
    }
    StartTracking(t0, t1);
  }

  CINEVOL_HD void StartTracking(float t0, float t1) {
    majorants_ = MajorantIterator(s_.majorants, ray_.origin, ray_.direction, t0, t1);
    segment_ = {t0, t0, 0.0f};  // empty: the first step enters the first brick
    dt_ = 0.0f;
    phase_ = Phase::kTracking;
  }

  // One exponential step inside the current brick, or the next brick. Steps
  // add up from the brick's entry, not onto t: far from the ray's origin a
  // step smaller than t's precision would leave t where it was. Empty bricks
  // (majorant 0) cost one DDA step and no volume fetch.
  CINEVOL_HD void TrackStep() {
    if (segment_.sigma_maj > 0.0f) {
      dt_ -= logf(1.0f - rng_.Uniform()) / segment_.sigma_maj;
      const float length = segment_.t_max - segment_.t_min;
      if (dt_ < length) return Collide(fminf(segment_.t_min + dt_, segment_.t_max));
    }
    dt_ = 0.0f;  // memoryless: restart in the next brick
    if (!majorants_.Next(segment_)) LeftRange();
  }

  CINEVOL_HD void LeftRange() {
    if (shadow_) {
      phase_ = Phase::kShadowEnded;
    } else {
      EndFlight(Outcome::kEscaped);
    }
  }

  // A tentative collision at t: real (flight) or a factor of the
  // transmittance (shadow ray). Each takes one from the path's budget.
  CINEVOL_HD void Collide(float t) {
    if (--budget_ < 0) {
      if (shadow_) {
        transmittance_ = 0.0f;
        phase_ = Phase::kShadowEnded;
      } else {
        EndFlight(Outcome::kAbsorbedByBudget);
      }
      return;
    }
    const float sigma_maj = segment_.sigma_maj;
    Classified c;
    const float sigma_t = Extinction(ray_.origin + ray_.direction * t, c);
    if (!shadow_) {
      if (rng_.Uniform() * sigma_maj < sigma_t) {
        t_hit_ = t;
        hit_ = c;
        EndFlight(Outcome::kHit);
      }
      return;
    }
    transmittance_ *= fmaxf(0.0f, 1.0f - sigma_t / sigma_maj);
    if (transmittance_ < 0.05f) {
      if (rng_.Uniform() < 0.75f) {
        transmittance_ = 0.0f;
        phase_ = Phase::kShadowEnded;
        return;
      }
      transmittance_ *= 4.0f;
    }
  }

  // What a flight found: light crossed and escaped, or a real collision where
  // the path shades, samples a light (a shadow ray) and its next direction.
  CINEVOL_HD void OnFlightEnded() {
    if (outcome_ == Outcome::kAbsorbedByBudget) {
      ++budget_ends_;
      return Finish();
    }
    const bool from_camera = depth_ == 0;
    const bool hit = outcome_ == Outcome::kHit;
    result_.radiance += beta_ * CrossedLights(ray_, hit ? t_hit_ : kInfiniteDistance, from_camera);
    if (!hit) {
      result_.radiance += beta_ * EscapedRadiance(ray_.direction, from_camera);
      return Finish();
    }
    const Vec3f p = ray_.origin + ray_.direction * t_hit_;
    const Material m = MaterialOf(hit_);
    if (from_camera) {
      result_.first_hit = p;
      result_.albedo = m.diffuse;
      result_.hit = true;
    }
    if constexpr (kWithEmission)
      result_.radiance += beta_ * s_.transfer.Emission(hit_.entry, kWithLabels ? hit_.label.table : 0);
    if (depth_ >= MaxBounces()) return Finish();

    const Vec3f wo = -ray_.direction;
    const Scatterer sc = MakeScatterer(p, wo, m);
    Vec3f light_dir;
    float light_distance;
    const bool shadow = SampleDirectLight(p, wo, sc, light_dir, light_distance);
    continues_ = SampleNextDirection(wo, sc);
    if (shadow) return StartShadow(p, light_dir, light_distance);
    ray_.origin = p;
    OnShadowEnded();  // no shadow ray: go on at once
  }

  // The shadow ray (its origin the collision) is done: its light counts, and
  // the path goes on from there.
  CINEVOL_HD void OnShadowEnded() {
    if (shadow_) result_.radiance += pending_ * transmittance_;
    if (!continues_) return Finish();
    ++depth_;
    StartFlight({ray_.origin, next_direction_});
  }

  CINEVOL_HD int MaxBounces() const { return kMultiple ? s_.max_bounces : MinInt(s_.max_bounces, 1); }

  // Samples the direction of the next flight into next_direction_, with its
  // weight in beta_ and its pdf in scatter_pdf_; false where the path ends.
  CINEVOL_HD bool SampleNextDirection(Vec3f wo, const Scatterer& sc) {
    // The last scattering event only matters through what its sampled ray
    // can reach: hittable lights or an emitting volume.
    if (depth_ + 1 >= MaxBounces() && !s_.has_hittable_lights && !kWithEmission) return false;
    const float u0 = rng_.Uniform(), u1 = rng_.Uniform(), u2 = rng_.Uniform();
    const Vec3f weight = SampleScatter(sc, wo, u0, u1, u2, next_direction_, scatter_pdf_);
    if (!(scatter_pdf_ > 0.0f) || !(MaxComponent(weight) > 0.0f)) return false;
    beta_ *= weight;
    if constexpr (kMultiple) {
      // Terminate with probability 1 - max(beta) (as pbrt does): survivors
      // return to a throughput near 1, so weights never grow without bound.
      if (depth_ + 1 >= kRouletteDepth) {
        const float q = fmaxf(0.0f, 1.0f - MaxComponent(beta_));
        if (rng_.Uniform() < q) return false;
        beta_ *= 1.0f / (1.0f - q);
      }
    }
    return true;
  }

  CINEVOL_HD int SampleableLights() const {
    return s_.light_count + (s_.environment.kind != Environment::Kind::kNone ? 1 : 0);
  }

  CINEVOL_HD float LightSelectionPdf() const { return kChooseLight ? 1.0f / float(SampleableLights()) : 1.0f; }

  // Hybrid scattering: the BRDF with Exposure Render's probability, else the phase function.
  CINEVOL_HD Scatterer MakeScatterer(Vec3f p, Vec3f wo, const Material& m) {
    if (cap_face_ >= 0) {
      // The capped face's normal, out of the kept region: towards the ray.
      const Vec3f normal = -Xyz(s_.clip.half_spaces[cap_face_]);
      return {true, m.diffuse, m.specular, fmaxf(m.roughness * m.roughness, 1e-3f), normal, 0.0f};
    }
    Scatterer sc{false, m.diffuse, {}, 0.0f, {}, s_.transfer.phase_g};
    if constexpr (kWithGradients) {
      const Vec3f grad = s_.volume.template Gradient<kCubic>(p);
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

  // Next-event estimation towards one light: the light's contribution but
  // for the transmittance goes to pending_; true where a shadow ray must
  // find that transmittance, towards `w` over `distance`.
  CINEVOL_HD bool SampleDirectLight(Vec3f p, Vec3f wo, const Scatterer& sc, Vec3f& w, float& distance) {
    const int n = SampleableLights();
    if (n == 0) return false;
    const int i = kChooseLight ? MinInt(static_cast<int>(rng_.Uniform() * float(n)), n - 1) : 0;
    const float u1 = rng_.Uniform(), u2 = rng_.Uniform();
    LightSample ls;
    const bool sampled = i < s_.light_count ? SampleLight(s_.lights[i], p, u1, u2, ls)
                                            : SampleEnvironment<kWithMap>(s_.environment, u1, u2, ls);
    if (!sampled) return false;
    float scatter_pdf;
    const Vec3f f = EvalScatter(sc, wo, ls.wi, scatter_pdf);
    if (!(MaxComponent(f) > 0.0f) || !(MaxComponent(ls.radiance) > 0.0f)) return false;
    const float light_pdf = LightSelectionPdf() * ls.pdf;
    const float mis = ls.delta ? 1.0f : PowerHeuristic(light_pdf, scatter_pdf);
    pending_ = beta_ * f * ls.radiance * (mis / light_pdf);
    w = ls.wi;
    distance = ls.distance;
    return true;
  }

  // Area lights the ray crosses before t_max, weighted against NEE.
  CINEVOL_HD Vec3f CrossedLights(const Ray& ray, float t_max, bool from_camera) const {
    Vec3f sum{};
    for (int i = 0; i < s_.light_count; ++i) {
      const Light& light = s_.lights[i];
      if (light.kind != LightKind::kArea || (from_camera && !light.visible)) continue;
      Vec3f radiance;
      float light_pdf;
      if (!IntersectAreaLight(light, ray.origin, ray.direction, t_max, radiance, light_pdf)) continue;
      sum += radiance * (from_camera ? 1.0f : PowerHeuristic(scatter_pdf_, LightSelectionPdf() * light_pdf));
    }
    return sum;
  }

  CINEVOL_HD Vec3f EscapedRadiance(Vec3f d, bool from_camera) const {
    if (s_.environment.kind == Environment::Kind::kNone || (from_camera && !s_.environment.visible)) return {};
    const Vec3f radiance = EnvironmentRadiance<kWithMap>(s_.environment, d);
    if (from_camera) return radiance;
    return radiance * PowerHeuristic(scatter_pdf_, LightSelectionPdf() * EnvironmentPdf<kWithMap>(s_.environment, d));
  }

  CINEVOL_HD static Vec3f Inverse(Vec3f d) { return {1.0f / d.x, 1.0f / d.y, 1.0f / d.z}; }

  const RenderScene& s_;
  Pcg32 rng_{0, 0};
  Phase phase_ = Phase::kDone;
  // The tracking under way, along ray_ (a flight's or a shadow ray's).
  Ray ray_{};
  bool shadow_ = false;
  MajorantIterator majorants_;
  MajorantSegment segment_{};
  float dt_ = 0.0f;           // distance drawn into the current brick
  float transmittance_ = 1;   // shadow ray
  Outcome outcome_ = Outcome::kEscaped;  // flight
  float t_hit_ = 0.0f;        // flight, kHit: where, and what is there
  Classified hit_;
  int cap_face_ = -1;         // flight, kHit on a capped face: that face's half-space
  // The path.
  PathResult result_;
  Vec3f beta_{1, 1, 1};
  float scatter_pdf_ = 0.0f;  // pdf of the direction the flight under way was sampled with
  int depth_ = 0;             // scattering events so far
  Vec3f pending_{};           // NEE contribution waiting for its shadow ray's transmittance
  Vec3f next_direction_{};    // where the path goes after the shadow ray,
  bool continues_ = false;    // if it goes on
  int budget_ = kMaxPathCollisions;  // tentative collisions left to the path
  int collisions_ = 0, budget_ends_ = 0;
};

// The samples of one pixel: spp paths, stratified per frame, seeded by
// (seed, frame, pixel, sample) so the image depends neither on thread or block
// order nor on which lane traced which path.
struct PixelSamples {
  int x = 0, y = 0;
  std::uint64_t key = 0;
  Vec3f sum{}, albedo{};
  Vec4f first_hit{};
  float nearest = kInfiniteDistance;

  CINEVOL_HD PixelSamples() = default;
  CINEVOL_HD PixelSamples(const RenderScene& s, int px, int py)
      : x(px), y(py), key(HashCombine(HashCombine(s.seed, s.frame), std::uint64_t(Index(s)))) {}

  CINEVOL_HD int Index(const RenderScene& s) const { return y * s.camera.width + x; }

  // Sample k's camera ray and random numbers.
  CINEVOL_HD Ray CameraRay(const RenderScene& s, int k) const {
    const std::uint32_t pattern = static_cast<std::uint32_t>(key);
    float fx, fy, lx, ly;
    CorrelatedMultiJitter(k, s.spp, pattern, fx, fy);
    CorrelatedMultiJitter(k, s.spp, pattern ^ 0x5bd1e995U, lx, ly);
    const float px = float(x) + 0.5f + SampleTruncatedGaussian(fx, kPixelFilterSigma, kPixelFilterRadius);
    const float py = float(y) + 0.5f + SampleTruncatedGaussian(fy, kPixelFilterSigma, kPixelFilterRadius);
    return s.camera.GenerateRay(px, py, lx, ly);
  }
  CINEVOL_HD Pcg32 Random(int k) const { return Pcg32(key, std::uint64_t(k)); }

  CINEVOL_HD void Add(const RenderScene& s, const PathResult& r) {
    // A non-finite sample would poison the accumulation and the denoiser's
    // history; the integrator is built not to make one, this is the backstop.
    if (IsFinite(r.radiance)) sum += r.radiance;
    albedo += r.albedo;
    if (r.hit) {
      const float d = Length(r.first_hit - s.camera.eye);
      if (d < nearest) {
        nearest = d;
        first_hit = ToVec4(r.first_hit, 1.0f);
      }
    }
  }

  CINEVOL_HD void Write(const RenderScene& s, const FrameTargets& out) const {
    const int pixel = Index(s);
    const Vec3f radiance = sum / float(s.spp);
    out.radiance[pixel] = radiance;
    out.first_hit[pixel] = first_hit;
    out.albedo[pixel] = albedo / float(s.spp);
    out.accumulated[pixel] += radiance;
  }
};

// Renders pixel (x, y), each path to its end (the CPU backend).
template <unsigned kFeatures>
CINEVOL_HD void RenderPixel(const RenderScene& s, int x, int y, const FrameTargets& out) {
  PixelSamples pixel(s, x, y);
  PathTracer<kFeatures> tracer(s);
  for (int k = 0; k < s.spp; ++k) pixel.Add(s, tracer.Trace(pixel.CameraRay(s, k), pixel.Random(k)));
  pixel.Write(s, out);
}

}  // namespace cinevol

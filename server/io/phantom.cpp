// Built-in phantoms, generated procedurally. The head is built from
// ellipsoids and tubes given by approximate signed distances (mm), blended with
// one voxel of partial-volume smoothing so gradients look like a real scan.
#include "io/phantom.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <fmt/format.h>

#include "core/error.h"
#include "core/parallel_for.h"

namespace cinevol {
namespace {

// Hounsfield units of the tissues in the head phantom.
namespace hu {
constexpr float kAir = -1000, kSkin = 40, kFat = -90, kMuscle = 50, kCorticalBone = 1400,
                kDiploe = 450, kCsf = 8, kGreyMatter = 40, kWhiteMatter = 28, kVitreous = 12,
                kLens = 70, kContrastBlood = 350, kEnamel = 2500;
}  // namespace hu

struct Ellipsoid {
  Vec3f centre, radii;
  // Approximate signed distance: exact on the axes, conservative elsewhere.
  float Sdf(Vec3f p) const {
    return (Length((p - centre) / radii) - 1.0f) * MinComponent(radii);
  }
};

// A tube of radius r along the segment a-b.
struct Tube {
  Vec3f a, b;
  float r;
  float Sdf(Vec3f p) const {
    const Vec3f ab = b - a;
    const float t = std::clamp(Dot(p - a, ab) / Dot(ab, ab), 0.0f, 1.0f);
    return Length(p - (a + ab * t)) - r;
  }
};

// Fraction of a voxel of size h inside the surface sdf = 0.
float Coverage(float sdf, float h) { return std::clamp(0.5f - sdf / h, 0.0f, 1.0f); }

// Deterministic per-voxel noise in [-1, 1], like CT quantum noise.
float HashNoise(std::uint32_t i) {
  i ^= i >> 16;
  i *= 0x7feb352dU;
  i ^= i >> 15;
  i *= 0x846ca68bU;
  i ^= i >> 16;
  return static_cast<float>(i & 0xffffff) / float(0x7fffff) - 1.0f;
}

// Patient coordinates in mm (LPS: +x left, +y posterior, +z superior).
float HeadValue(Vec3f p, float h) {
  static const Ellipsoid kCranium{{0, 10, 25}, {70, 88, 80}};
  static const Ellipsoid kScalp{{0, 10, 25}, {79, 97, 89}};
  static const Ellipsoid kFace{{0, -30, -30}, {58, 62, 55}};
  static const Ellipsoid kNeck{{0, 12, -95}, {48, 52, 60}};
  static const Ellipsoid kNose{{0, -92, -22}, {9, 14, 20}};
  static const Ellipsoid kEyes[2] = {{{-32, -74, -4}, {12, 12, 12}}, {{32, -74, -4}, {12, 12, 12}}};
  static const Ellipsoid kLenses[2] = {{{-32, -85, -4}, {5, 2, 5}}, {{32, -85, -4}, {5, 2, 5}}};
  static const Ellipsoid kVentricles[2] = {{{-11, 8, 32}, {6, 28, 10}}, {{11, 8, 32}, {6, 28, 10}}};
  static const Ellipsoid kThirdVentricle{{0, 10, 18}, {2.5f, 14, 9}};
  static const Tube kSpine{{0, 28, -128}, {0, 22, -45}, 10};
  // Facial skeleton: orbits carved into the skull, maxilla with its sinus,
  // zygomatic arches, mandible and two rows of teeth.
  static const Ellipsoid kOrbits[2] = {{{-31, -70, -2}, {17, 16, 16}}, {{31, -70, -2}, {17, 16, 16}}};
  static const Ellipsoid kMaxilla{{0, -52, -36}, {36, 30, 20}};
  static const Ellipsoid kSinus{{0, -50, -33}, {27, 20, 12}};
  static const Ellipsoid kNasalCavity{{0, -74, -22}, {8, 16, 15}};
  static const Tube kFaceBones[] = {
      {{-56, -50, -12}, {-66, -5, -14}, 5.0f},  // zygomatic arches
      {{56, -50, -12}, {66, -5, -14}, 5.0f},
      {{-50, -2, -22}, {-46, -20, -66}, 7.0f},  // mandibular rami
      {{50, -2, -22}, {46, -20, -66}, 7.0f},
      {{-46, -20, -66}, {-30, -58, -74}, 7.0f},  // body of the mandible
      {{46, -20, -66}, {30, -58, -74}, 7.0f},
      {{-30, -58, -74}, {0, -72, -76}, 7.0f},
      {{30, -58, -74}, {0, -72, -76}, 7.0f},
  };
  static const Tube kVessels[] = {
      {{-24, -4, -128}, {-16, 2, -25}, 3.0f},  // internal carotids
      {{24, -4, -128}, {16, 2, -25}, 3.0f},
      {{-16, 2, -25}, {-10, -12, -12}, 2.5f},  // anterior cerebral
      {{16, 2, -25}, {10, -12, -12}, 2.5f},
      {{-10, -12, -12}, {-2, -30, 30}, 1.8f},
      {{10, -12, -12}, {2, -30, 30}, 1.8f},
      {{-16, 2, -25}, {-48, 0, -5}, 2.2f},  // middle cerebral
      {{16, 2, -25}, {48, 0, -5}, 2.2f},
      {{-48, 0, -5}, {-58, 20, 35}, 1.5f},
      {{48, 0, -5}, {58, 20, 35}, 1.5f},
      {{0, 30, -60}, {0, 20, -25}, 2.5f},  // basilar
      {{0, 20, -25}, {-30, 45, 0}, 1.8f},  // posterior cerebral
      {{0, 20, -25}, {30, 45, 0}, 1.8f},
  };

  const float soft = std::min({kScalp.Sdf(p), kFace.Sdf(p), kNeck.Sdf(p), kNose.Sdf(p)});
  float v = hu::kAir;
  auto paint = [&](float sdf, float value) { v += (value - v) * Coverage(sdf, h); };

  paint(soft, hu::kSkin);
  paint(soft + 2.5f, hu::kFat);
  paint(soft + 6.0f, hu::kMuscle);
  paint(kSpine.Sdf(p), hu::kCorticalBone);
  paint(kSpine.Sdf(p) + 2.0f, hu::kDiploe);
  const float skull = kCranium.Sdf(p);
  paint(skull, hu::kCorticalBone);
  paint(skull + 2.0f, hu::kDiploe);
  paint(skull + 6.0f, hu::kCorticalBone);
  paint(skull + 8.0f, hu::kCsf);
  paint(skull + 9.5f, hu::kGreyMatter);
  paint(skull + 14.0f, hu::kWhiteMatter);
  for (const Ellipsoid& e : kOrbits) paint(e.Sdf(p), hu::kFat);
  paint(kMaxilla.Sdf(p), hu::kCorticalBone);
  paint(kMaxilla.Sdf(p) + 3.0f, hu::kDiploe);
  paint(kSinus.Sdf(p), hu::kAir);
  paint(kNasalCavity.Sdf(p), hu::kAir);
  for (const Tube& t : kFaceBones) {
    paint(t.Sdf(p), hu::kCorticalBone);
    paint(t.Sdf(p) + 2.5f, hu::kDiploe);
  }
  // Teeth: enamel crowns along the upper and lower arches.
  for (int i = 0; i < 14; ++i) {
    const float a = (float(i) - 6.5f) / 6.5f * 1.35f;  // radians from the midline
    const Vec3f upper{36.0f * std::sin(a), -14.0f - 58.0f * std::cos(a), -53.0f};
    paint(Ellipsoid{upper, {3.6f, 3.6f, 5.0f}}.Sdf(p), hu::kEnamel);
    paint(Ellipsoid{upper + Vec3f{0, 0, -10.5f}, {3.6f, 3.6f, 5.0f}}.Sdf(p), hu::kEnamel);
  }
  for (const Ellipsoid& e : kVentricles) paint(e.Sdf(p), hu::kCsf);
  paint(kThirdVentricle.Sdf(p), hu::kCsf);
  for (const Ellipsoid& e : kEyes) paint(e.Sdf(p), hu::kVitreous);
  for (const Ellipsoid& e : kLenses) paint(e.Sdf(p), hu::kLens);
  for (const Tube& t : kVessels) paint(t.Sdf(p), hu::kContrastBlood);
  return v;
}

}  // namespace

Volume MakePhantom(const v1::Phantom& spec) {
  const PhantomSpec p = ResolvePhantom(spec);
  const int n = p.size;
  const float half = 0.5f * n * p.spacing;
  std::vector<float> values(std::size_t(n) * n * n);

  // Voxel centres in mm, relative to the volume's centre.
  auto centre_of = [&](int x, int y, int z) {
    return Vec3f{(x + 0.5f) * p.spacing - half, (y + 0.5f) * p.spacing - half,
                 (z + 0.5f) * p.spacing - half};
  };
  ParallelFor(n, [&](std::int64_t z) {
    for (int y = 0; y < n; ++y) {
      for (int x = 0; x < n; ++x) {
        const std::size_t i = (std::size_t(z) * n + y) * n + x;
        const Vec3f c = centre_of(x, y, static_cast<int>(z));
        float v;
        if (p.kind == v1::Phantom::HEAD) {
          // The head is modelled in mm for a 256 mm field of view; other sizes
          // and spacings scale it to fit.
          const float to_model = 256.0f / (n * p.spacing);
          v = HeadValue(c * to_model, p.spacing * to_model);
          v = std::nearbyint(v + 6.0f * HashNoise(static_cast<std::uint32_t>(i)));
        } else if (p.kind == v1::Phantom::CUBE) {
          v = MaxComponent(Abs(c)) <= p.radius ? p.value : p.background;
        } else {
          v = Length(c) <= p.radius ? p.value : p.background;
        }
        values[i] = v;
      }
    }
  });

  VolumeMetadata meta;
  meta.source = PhantomName(spec);
  meta.modality = p.kind == v1::Phantom::HEAD ? "CT" : "";
  meta.value_unit = p.kind == v1::Phantom::HEAD ? "HU" : "";
  meta.original_type = "generated";
  meta.origin_mm = {-half + 0.5 * p.spacing, -half + 0.5 * p.spacing, -half + 0.5 * p.spacing};
  return Volume({n, n, n}, {p.spacing, p.spacing, p.spacing}, std::move(values), std::move(meta));
}

}  // namespace cinevol

// Everything one frame's kernels read, as POD views passed by value, plus
// the feature set that picks a specialised integrator.
#pragma once

#include <cstdint>

#include "core/camera.h"
#include "core/clip_region.h"
#include "core/fused_view.h"
#include "core/label_view.h"
#include "core/lights.h"
#include "core/transfer_view.h"
#include "core/volume_view.h"
#include "render/majorant_grid.h"

namespace cinevol {

// Features a scene may use. The integrator is instantiated for every subset
// so that a scene pays only for what it uses; kAllFeatures renders anything.
enum RenderFeature : unsigned {
  kGradients = 1u << 0,           // gradientFactor > 0: gradients and the BRDF
  kEmission = 1u << 1,            // the transfer function emits
  kEnvironmentMap = 1u << 2,      // the environment is an HDR map
  kMultipleScattering = 1u << 3,  // maxBounces > 1: the bounce loop and Russian roulette
  kSeveralLights = 1u << 4,       // more than one light to choose from
  // What clinical scenes add (issues 22, 59). They change what is computed,
  // so a request never forces them; and they come only with every feature
  // above, so they add 7 integrators, not 224 (kIntegratorVariants).
  kTricubic = 1u << 5,  // tricubic reconstruction
  kLabels = 1u << 6,    // a segmentation styles the classification
  kFusion = 1u << 7,    // a second volume adds its extinction and material (Scene.fusion)
};
// Every feature that only specialises, never changes the image.
inline constexpr unsigned kAllFeatures = (1u << 5) - 1;
// On a GPU only the integrators with all of kAllFeatures read a volume no
// texture holds (voxels one by one: too large for a texture, or
// RendererOptions::volume_texture off); the others read textures alone and
// carry no code for the voxels, which their lookups would each call out to
// (cuda_renderer.cu). The CPU reads its voxels either way.
constexpr bool ReadsTexturesOnly(unsigned features) { return (features & kAllFeatures) != kAllFeatures; }
inline constexpr unsigned kClinicalFeatures = kTricubic | kLabels | kFusion;

// The integrators compiled: every subset of kAllFeatures, then kAllFeatures
// with each non-empty subset of kClinicalFeatures.
inline constexpr unsigned kIntegratorVariants = (kAllFeatures + 1) + 7;
constexpr unsigned VariantFeatures(unsigned variant) {
  return variant <= kAllFeatures ? variant : kAllFeatures | ((variant - kAllFeatures) << 5);
}
constexpr unsigned VariantOf(unsigned features) {
  return features & kClinicalFeatures ? kAllFeatures + (features >> 5) : features;
}

struct RenderScene {
  VolumeView volume;
  TransferView transfer;
  MajorantGridView majorants;
  ClipRegion clip;                // what the crop box and clip planes keep
  LabelView labels;               // the segmentation's styles; none by default
  FusedView fused;                // a second volume; none by default
  const Light* lights = nullptr;  // in the backend's memory
  int light_count = 0;
  Environment environment;
  Camera camera;
  int spp = 1;
  int max_bounces = 4;
  std::uint64_t seed = 0;
  std::uint32_t frame = 0;  // frame index: with seed and pixel, seeds the samples
  bool has_emission = false;

  // Lights that sampled directions can hit: area lights and the environment.
  bool has_hittable_lights = false;
};

// Per-pixel outputs in the backend's memory.
struct FrameTargets {
  Vec3f* radiance = nullptr;     // this frame: mean over its samples
  Vec4f* first_hit = nullptr;    // xyz: nearest first real collision (mm); w: 1 hit, 0 escaped
  Vec3f* accumulated = nullptr;  // running sum of radiance since the last reset
  Vec3f* albedo = nullptr;       // mean diffuse colour at the first collision (1 where escaped)
  // Where set (FrameRequest::surface_normals): the volume's unit gradient at
  // the nearest first hit, facing the eye, times the probability that the
  // hybrid scattering takes it for a surface there; 0 where the ray escaped
  // or the scene shades without gradients. A denoiser's normal stop.
  Vec3f* surface_normal = nullptr;
  // The frame is the first since the reset: it writes `accumulated` rather
  // than adding to it, so a reset clears nothing (a moving view's every frame
  // is one; clearing cost a pass over the buffer and a read of it cold).
  bool accumulation_starts = false;
};

// The smallest feature set that renders `scene` exactly.
inline unsigned FeaturesOf(const RenderScene& scene) {
  unsigned f = 0;
  if (scene.transfer.gradient_factor > 0.0f) f |= kGradients;
  if (scene.has_emission) f |= kEmission;
  if (scene.environment.kind == Environment::Kind::kMap) f |= kEnvironmentMap;
  if (scene.max_bounces > 1) f |= kMultipleScattering;
  const int sampleable = scene.light_count + (scene.environment.kind != Environment::Kind::kNone ? 1 : 0);
  if (sampleable > 1) f |= kSeveralLights;
  if (scene.volume.tricubic) f |= kTricubic;
  if (scene.labels.voxels) f |= kLabels;
  if (scene.fused.present()) f |= kFusion;
  return f;
}

}  // namespace cinevol

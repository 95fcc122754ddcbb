// The transfer function on the host: piecewise-linear control points over
// the voxel value, and the lookup table the renderer samples.
#pragma once

#include <vector>

#include "core/vec.h"

namespace cinevol {

struct TransferPoint {
  float value = 0;      // voxel value in the data's units
  float opacity = 0;    // [0, 1]
  Vec3f diffuse;        // [0, 1]
  Vec3f specular;       // [0, 1]
  float roughness = 0;  // [0, 1]
  Vec3f emission;       // >= 0
};

struct TransferFunction {
  std::vector<TransferPoint> points;  // sorted by strictly increasing value
  float density_scale = 1.0f;         // per mm: sigma_t = opacity * density_scale
  float gradient_factor = 1.0f;       // >= 0; 0 = phase function only
  float phase_g = 0.0f;               // Henyey-Greenstein anisotropy
};

// Evaluates the piecewise-linear function at `value`: constant beyond the ends.
TransferPoint Evaluate(const TransferFunction& tf, float value);

// The largest opacity the function takes over [lo, hi].
float MaxOpacity(const TransferFunction& tf, float lo, float hi);

// Gradient factors above this act as this: the surface probability
// opacity * (1 - exp(-25 g^3 |grad|)) is then the opacity wherever the
// normalised gradient passes 1e-9 (a billionth of the value range per voxel),
// and g^3 stays finite.
inline constexpr float kMaxGradientFactor = 1000.0f;

// The transfer function sampled at `kEntries` values evenly spaced over
// [value_min, value_max] (the volume's range; a constant volume's gets a
// width). The renderer interpolates linearly between entries; the majorant
// grid bounds extinction from the same entries, so bounds are exact for what
// is rendered. Extinction is clamped to `max_sigma_t` (per mm), the gradient
// factor to kMaxGradientFactor.
struct TransferTable {
  static constexpr int kEntries = 4096;
  float value_min = 0, value_max = 1;
  std::vector<float> sigma_t;                    // per mm
  std::vector<Vec4f> diffuse_opacity;            // rgb diffuse, a opacity
  std::vector<Vec4f> specular_roughness;         // rgb specular, a roughness
  std::vector<Vec4f> emission;                   // rgb emission
  float gradient_factor = 1.0f;
  float phase_g = 0.0f;
  bool has_emission = false;
};

TransferTable BuildTransferTable(const TransferFunction& tf, float value_min, float value_max,
                                 float max_sigma_t = 3.4e38f);

}  // namespace cinevol

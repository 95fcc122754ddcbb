// The preset library's tables: transfer functions in our model (opacity,
// colour, specular, roughness, the surface/volume blend), each saying where
// its numbers come from. server/io/presets.h turns them into scenes.
#pragma once

#include <vector>

namespace cinevol {

// The units of a preset's control-point values.
enum class PresetScale {
  kHu,      // Hounsfield units: CT in HU only
  // Fractions of the volume's automatic window: 0 is the foreground
  // threshold (Otsu's, separating air or background from the subject), 1 the
  // 99.5th percentile of the voxels above it. For data without absolute
  // units: MR, CT not in HU, micro-CT.
  kWindow,
};

struct PresetColor {
  float r, g, b;  // linear RGB, [0, 1]
};

struct PresetPoint {
  float value;           // in the preset's scale
  float opacity;         // [0, 1]; extinction = opacity * density_scale
  PresetColor diffuse;   // albedo
  float specular;        // grey specular reflectance, [0, 1]
  float roughness;       // [0, 1]
  PresetColor emission{0, 0, 0};
};

struct PresetDefinition {
  const char* name;         // lower-case with dashes, e.g. "ct-coronary"
  const char* description;  // one line for people: what it shows
  const char* origin;       // where the numbers come from
  PresetScale scale;
  float density_scale;      // per mm
  float gradient_factor;    // the surface/volume blend: 0 volumetric only, larger more surface-like
  std::vector<PresetPoint> points;  // strictly increasing values
};

// Every preset, in the order docs/presets.md lists them.
const std::vector<PresetDefinition>& PresetLibrary();

}  // namespace cinevol

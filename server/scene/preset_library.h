// The preset library's tables: transfer functions in our model (opacity,
// colour, specular, roughness, the surface/volume blend), each saying where
// its numbers come from. server/scene/presets.h turns them into scenes.
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
  // The subject's two phases: 0 the foreground threshold, 1 the split
  // between a faint phase and a much brighter, smaller one (micro-CT bone
  // in soft tissue) or, where the histogram shows none, the subject's
  // surface just above the threshold; 2 the 99.5th percentile.
  kPhases,
};

// How a CT preset follows the blood pool of a contrast-enhanced CT (a
// histogram peak between 150 and 700 HU; ValueWindow::blood).
enum class ContrastRule {
  kNone,
  // Bone presets: on a contrast CT the ramp moves up to start at the top of
  // the blood pool (its upper edge), over 0.6 of its width: contrast blood
  // stays hidden and the cortex above it shows.
  kAboveBloodPool,
  // Angiography presets: values are HU for a reference pool (peak
  // kReferenceBloodHu, upper edge kReferenceBloodTopHu); on a contrast CT,
  // values up to the reference peak map linearly onto soft tissue..peak,
  // those between peak and edge onto the volume's, and those above shift
  // with the edge.
  kOnBloodPool,
};
inline constexpr float kSoftTissueHu = 40.0f, kReferenceBloodHu = 400.0f, kReferenceBloodTopHu = 550.0f;

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
  // Per mm; for kPhases presets per voxel of the smallest spacing
  // (ValueWindow::voxel_mm): data of unknown kind often has no reliable
  // scale in its spacing either (micro-CT at 0.02 mm, nominal 1 mm NIfTI),
  // and a surface should be as sharp in voxels whatever the resolution.
  float density_scale;
  float gradient_factor;    // the surface/volume blend: 0 volumetric only, larger more surface-like
  std::vector<PresetPoint> points;  // strictly increasing values
  ContrastRule contrast = ContrastRule::kNone;
};

// Every preset, in the order docs/presets.md lists them.
const std::vector<PresetDefinition>& PresetLibrary();

}  // namespace cinevol

// Transfer-function presets (the tables are in preset_library.cpp) turned
// into scene parts for a given volume: HU presets as they are, window presets
// onto the volume's automatic window; and the scene a session starts from
// when it names only a preset.
#pragma once

#include <cmath>
#include <string>
#include <string_view>
#include <vector>

#include "cinevol/v1/scene.pb.h"
#include "cinevol/v1/service.pb.h"
#include "core/value_histogram.h"
#include "core/volume.h"
#include "scene/preset_library.h"

namespace cinevol {

std::vector<std::string> PresetNames();

bool IsPreset(std::string_view name);

// Throws InputError naming the presets for an unknown name.
const PresetDefinition& FindPreset(std::string_view name);

// What presets read from a volume's histogram. PresetScale::kWindow maps 0
// and 1 to `lo` and `hi`: Otsu's threshold (the subject against its
// background) and the 99.5th percentile above it; for MR this is the
// automatic window/level. kPhases maps 0, 1, 2 to `lo`, `dense`, `hi`.
struct ValueWindow {
  float lo = 0, hi = 1;
  // Where a small phase far brighter than the rest of the subject begins
  // (micro-CT bone in soft tissue), else the subject's surface just above
  // `lo`. NaN: lo + kSurfaceFraction * (hi - lo).
  float dense = NAN;
  // A contrast CT's blood pool: the peak of the histogram between 150 and
  // 700 HU and where it falls to a fifth of its height above it; 0 where
  // the histogram shows none (ContrastRule).
  float blood = 0, blood_top = 0;
  // The smallest voxel spacing, mm: kPhases presets' extinction is per voxel.
  float voxel_mm = 1;
};
inline constexpr float kSurfaceFraction = 0.08f;
// `voxel_mm`: the volume's smallest spacing, where the caller knows it.
ValueWindow AutoWindow(const ValueHistogram& histogram, float voxel_mm = 1.0f);
ValueWindow AutoWindow(const Volume& volume);

// The blood pool of a contrast CT in HU (ValueWindow::blood, blood_top), or
// {0, 0} where the histogram shows none.
struct BloodPool {
  float peak = 0, top = 0;
};
BloodPool FindBloodPool(const ValueHistogram& histogram);

// Where a small phase far brighter than the rest of the subject (above
// `lo`) begins, or NaN where the histogram shows none: Otsu's threshold on
// the subject's voxels, where the phase above it holds at most
// kDensePhaseMaxFraction of them and lies on average at least
// kDensePhaseContrast times as far above `lo` as the rest, and the rest is
// one tissue (standard deviation at most kDensePhaseMaxSpread of its mean
// height above `lo`). On the shared data only the micro-CT-like phantom
// qualifies: bonsai (35% above the split), engine (2.5 times), the MR head,
// CT_AVM and LIDC2 (spreads 0.56-0.68) do not.
inline constexpr double kDensePhaseMaxFraction = 0.2, kDensePhaseContrast = 2.75, kDensePhaseMaxSpread = 0.5;
float FindDensePhase(const ValueHistogram& histogram, float lo);

// The preset's control points, density scale and gradient factor, window
// presets mapped onto `window`. Throws InputError for an unknown name.
v1::TransferFunction MakePreset(std::string_view name, const ValueWindow& window);

// `tf` as points. Without points: its preset (or, with no preset either,
// the volume's default) expanded for the volume's values and spacing, with
// the preset's density scale and gradient factor where `tf` sets none, and
// the preset's name. With points: `tf` as it is.
v1::TransferFunction ExpandTransferFunction(const v1::TransferFunction& tf, const Volume& volume);
// Where `preset` does not fit `volume`, a sentence saying so and what would
// (a CT preset in HU on MR or on CT not in HU, an MR preset on CT in HU, an
// angiography preset on a CT without a blood-pool peak); else empty.
std::string PresetMisfit(std::string_view preset, const Volume& volume);

// The preset a volume of this kind shows by default.
std::string DefaultPreset(v1::VolumeKind kind);
std::string DefaultPreset(const Volume& volume);

// A scene around a preset, for viewers that name only a preset: an anterior
// view (superior for a thin slab of axial slices) framing what the preset shows, a warm key light above the viewer's
// left (not in the picture) and a dim gradient sky, placed relative to the
// view and the volume's size so that every volume is lit alike. The volume
// source and render settings are left unset. Throws InputError for an
// unknown preset.
v1::Scene MakePresetScene(std::string_view preset, const Volume& volume);

// A scene that names no lights takes the volume's default ones (those of
// MakePresetScene: the key light and the sky); with none it renders black.
// Returns whether it added them, for the caller to say so.
bool AddDefaultLights(v1::Scene& scene, const Volume& volume);

}  // namespace cinevol

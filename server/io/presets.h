// Transfer-function presets (the tables are in preset_library.cpp) turned
// into scene parts for a given volume: HU presets as they are, window presets
// onto the volume's automatic window; and the scene a session starts from
// when it names only a preset.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "cinevol/v1/scene.pb.h"
#include "cinevol/v1/service.pb.h"
#include "core/value_histogram.h"
#include "core/volume.h"
#include "io/preset_library.h"

namespace cinevol {

std::vector<std::string> PresetNames();

bool IsPreset(std::string_view name);

// Throws InputError naming the presets for an unknown name.
const PresetDefinition& FindPreset(std::string_view name);

// The values PresetScale::kWindow maps 0 and 1 to: Otsu's threshold (the
// subject against its background) and the 99.5th percentile above it. For
// MR this is the automatic window/level.
struct ValueWindow {
  float lo = 0, hi = 1;
};
ValueWindow AutoWindow(const ValueHistogram& histogram);

// The preset's control points, density scale and gradient factor, window
// presets mapped onto `window`. Throws InputError for an unknown name.
v1::TransferFunction MakePreset(std::string_view name, ValueWindow window);

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

// Transfer-function presets in the data's units: HU for CT; for MR, whose
// intensities have no absolute scale, fractions of the volume's value range.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "cinevol/v1/scene.pb.h"
#include "core/vec.h"

namespace cinevol {

// ct-bone, ct-soft-tissue, ct-vessels, ct-lung, mr-default.
std::vector<std::string> PresetNames();

bool IsPreset(std::string_view name);

// The preset's control points, density scale and gradient factor. `min_value`
// and `max_value` are the volume's range (used by MR presets only). Throws
// InputError for an unknown name.
v1::TransferFunction MakePreset(std::string_view name, float min_value, float max_value);

// A scene around a preset, for viewers that name only a preset: an anterior
// view, a warm area key light above the viewer's right and a dim gradient sky
// (the lighting of examples/ct-bone.json), scaled to a volume of `extent_mm`.
// The volume source and render settings are left unset. Throws InputError
// for an unknown preset.
v1::Scene MakePresetScene(std::string_view preset, Vec3f extent_mm);

}  // namespace cinevol

// Transfer-function presets in the data's units: HU for CT; for MR, whose
// intensities have no absolute scale, fractions of the volume's value range.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "cinevol/v1/scene.pb.h"

namespace cinevol {

// ct-bone, ct-soft-tissue, ct-vessels, ct-lung, mr-default.
std::vector<std::string> PresetNames();

bool IsPreset(std::string_view name);

// The preset's control points, density scale and gradient factor. `min_value`
// and `max_value` are the volume's range (used by MR presets only). Throws
// InputError for an unknown name.
v1::TransferFunction MakePreset(std::string_view name, float min_value, float max_value);

}  // namespace cinevol

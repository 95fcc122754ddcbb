// Built-in phantoms: a CT-like head in HU and simple analytic shapes for tests.
#pragma once

#include <string>

#include "cinevol/v1/scene.pb.h"
#include "core/volume.h"
#include "scene/phantom_spec.h"

namespace cinevol {

// Generates the phantom `spec` describes (defaults in scene.proto). The head
// is in HU, 256^3 at 1 mm by default; its tissues follow a real CT's values.
Volume MakePhantom(const v1::Phantom& spec);

}  // namespace cinevol

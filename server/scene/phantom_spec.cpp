// Phantom defaults and ranges.
#include "scene/phantom_spec.h"

#include <cmath>

#include <fmt/format.h>

#include "core/error.h"
#include "core/volume.h"

namespace cinevol {

PhantomSpec ResolvePhantom(const v1::Phantom& spec) {
  PhantomSpec p;
  p.kind = spec.kind();
  const bool head = p.kind == v1::Phantom::HEAD;
  p.size = spec.has_size() ? static_cast<int>(spec.size()) : (head ? 256 : 64);
  p.spacing = spec.has_spacing() ? spec.spacing() : 1.0f;
  p.value = spec.has_value() ? spec.value() : 1000.0f;
  p.background = spec.has_background() ? spec.background() : 0.0f;
  const float extent = p.size * p.spacing;
  p.radius = spec.has_radius() ? spec.radius()
                               : (p.kind == v1::Phantom::SPHERE ? 0.4f * extent : 0.5f * extent);
  if (p.kind == v1::Phantom::KIND_UNSPECIFIED) throw InputError("phantom: kind is not set");
  if (p.size < 1 || p.size > 1024) {
    throw InputError(fmt::format("phantom.size: {} is outside [1, 1024]", p.size));
  }
  if (!(p.spacing >= kMinSpacingMm && p.spacing <= 100.0f)) {
    throw InputError(fmt::format("phantom.spacing: {:g} mm is outside [{:g}, 100]", p.spacing, kMinSpacingMm));
  }
  if (!std::isfinite(p.value) || !std::isfinite(p.background) || !(p.radius >= 0.0f) ||
      !std::isfinite(p.radius)) {
    throw InputError("phantom: value, background and radius must be finite, radius >= 0");
  }
  return p;
}

void ValidatePhantom(const v1::Phantom& spec) { ResolvePhantom(spec); }

std::string PhantomName(const v1::Phantom& spec) {
  switch (spec.kind()) {
    case v1::Phantom::HEAD: return "phantom:head";
    case v1::Phantom::CUBE: return "phantom:cube";
    case v1::Phantom::SPHERE: return "phantom:sphere";
    default: return "phantom:?";
  }
}

}  // namespace cinevol

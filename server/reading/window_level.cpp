// Window presets and the automatic window.
#include "reading/window_level.h"

#include <algorithm>

namespace cinevol {

const std::vector<WindowPreset>& WindowPresets() {
  static const std::vector<WindowPreset> kPresets = {
      {"brain", {40, 80}},
      {"soft-tissue", {50, 350}},
      {"lung", {-600, 1500}},
      {"bone", {400, 1000}},
  };
  return kPresets;
}

std::optional<VoiWindow> FindWindowPreset(std::string_view name) {
  for (const WindowPreset& preset : WindowPresets()) {
    if (name == preset.name) return preset.window;
  }
  return std::nullopt;
}

VoiWindow AutoVoiWindow(const ValueHistogram& histogram) {
  const float background = histogram.OtsuThreshold();
  const double lo = histogram.Percentile(0.01, background);
  const double hi = std::max(histogram.Percentile(0.99, background), float(lo));
  // Width and centre such that lo is the last value at 0 and hi the first at
  // 255: the formula's ramp spans w - 1 and is centred on c - 0.5.
  return {(lo + hi) / 2 + 0.5, hi - lo + 1};
}

VoiWindow DefaultWindow(const Volume& volume, std::string* name) {
  const bool hounsfield = volume.metadata().value_unit == "HU";
  if (name) *name = hounsfield ? "soft-tissue" : "auto";
  return hounsfield ? *FindWindowPreset("soft-tissue") : AutoVoiWindow(volume.histogram());
}

}  // namespace cinevol

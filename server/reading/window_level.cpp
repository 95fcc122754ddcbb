// Window presets and the automatic window.
#include "reading/window_level.h"

#include <fmt/format.h>

#include <algorithm>

#include "core/error.h"
#include "core/log_safe.h"

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
  const std::optional<VoiWindow>& stored = volume.metadata().stored_window;
  if (name) *name = stored ? "stored" : hounsfield ? "soft-tissue" : "auto";
  if (stored) return *stored;
  return hounsfield ? *FindWindowPreset("soft-tissue") : AutoVoiWindow(volume.histogram());
}

VoiWindow WindowNamed(std::string_view name, const Volume& volume) {
  if (name.empty()) return DefaultWindow(volume);
  if (name == "auto") return AutoVoiWindow(volume.histogram());
  if (name == "stored") {
    if (volume.metadata().stored_window) return *volume.metadata().stored_window;
    throw InputError(
        fmt::format("window preset 'stored': {} stores no window (only DICOM can)", volume.metadata().source));
  }
  if (const auto preset = FindWindowPreset(name)) return *preset;
  throw InputError(
      fmt::format("'{}' is none of brain, soft-tissue, lung, bone, auto, stored", LogSafe(name)));
}

std::string WindowMisfit(std::string_view name, const Volume& volume) {
  if (!FindWindowPreset(name) || volume.metadata().value_unit == "HU") return {};
  return fmt::format("window '{}' is in Hounsfield units, and this volume's values are not: 'auto' spreads its own "
                     "values over the grey range",
                     LogSafe(name));
}

}  // namespace cinevol

// Window/level for reading slices: the DICOM VOI LINEAR function (PS3.3
// C.11.2.1.2) from values after the modality rescale (HU for CT) to 8-bit
// grey, the radiologists' named presets and an automatic window from the
// volume's histogram.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/volume.h"

namespace cinevol {

// VOI LINEAR to [0, 255], rounded to the nearest grey level:
//   x <= c - 0.5 - (w-1)/2  -> 0
//   x >  c - 0.5 + (w-1)/2  -> 255
//   else ((x - (c - 0.5)) / (w - 1) + 0.5) * 255
// Inline: slices call it once a pixel.
inline std::uint8_t ApplyVoiLinear(double x, const VoiWindow& window) {
  const double c = window.center - 0.5, half = (window.width - 1) / 2;
  if (x <= c - half) return 0;
  if (x > c + half) return 255;
  const double y = ((x - c) / (window.width - 1) + 0.5) * 255;
  return static_cast<std::uint8_t>(y + 0.5);
}

// A named window (--preset). Widths/levels as radiologists quote them.
struct WindowPreset {
  const char* name;
  VoiWindow window;
};
// brain 80/40, soft-tissue 350/50, lung 1500/-600, bone 1000/400 (width/level, HU).
const std::vector<WindowPreset>& WindowPresets();
// The preset called `name`; nullopt for another name.
std::optional<VoiWindow> FindWindowPreset(std::string_view name);

// The window that spreads a volume's non-background values over the grey
// range: background is what lies below Otsu's threshold (the split the
// presets use between air and subject); the window runs from the 1st to the
// 99th percentile of the rest, so 1% of the subject's voxels clip at each
// end. For MR and anything without HU.
VoiWindow AutoVoiWindow(const ValueHistogram& histogram);

// What a slice shows without a window asked for: the window its DICOM stores
// where there is one, else soft tissue for values in HU, the automatic window
// otherwise. `name` is set to what was chosen ("stored", "soft-tissue", "auto").
VoiWindow DefaultWindow(const Volume& volume, std::string* name = nullptr);

// The window called `name` for `volume`: a preset, "auto", "stored" (its
// DICOM's) or "" (DefaultWindow). Throws InputError for another name, or for
// "stored" where the volume stores none.
VoiWindow WindowNamed(std::string_view name, const Volume& volume);

// Where window `name` does not fit `volume` (a window in HU on values that
// are not), a sentence saying so; else empty.
std::string WindowMisfit(std::string_view name, const Volume& volume);

}  // namespace cinevol

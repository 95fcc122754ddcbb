// Display transform: exposure, a filmic curve (Narkowicz's ACES fit) and the
// sRGB transfer function. Runs where the frame was rendered.
#pragma once

#include <cstdint>

#include "core/hd.h"
#include "core/image.h"
#include "core/vec.h"

namespace cinevol {

CINEVOL_HD float LinearToSrgb(float c) {
  return c <= 0.0031308f ? 12.92f * c : 1.055f * powf(c, 1.0f / 2.4f) - 0.055f;
}

CINEVOL_HD float AcesFilm(float x) {
  x = fmaxf(x, 0.0f);
  return fminf((x * (2.51f * x + 0.03f)) / (x * (2.43f * x + 0.59f) + 0.14f), 1.0f);
}

// A channel's place on the 8-bit scale before rounding, [0, 255]: its code
// is this rounded. `scaled`: linear radiance times 2^exposure.
CINEVOL_HD float DisplayPosition(float scaled) {
  return fminf(fmaxf(LinearToSrgb(AcesFilm(scaled)) * 255.0f, 0.0f), 255.0f);
}

// Linear radiance to 8-bit sRGB; exposure_scale = 2^exposure. `position`,
// where not null, gets each channel's DisplayPosition. A non-finite pixel
// is black.
CINEVOL_HD void ToneMapPixel(Vec3f c, float exposure_scale, std::uint8_t* rgb, float* position = nullptr) {
  const bool finite = IsFinite(c);
  for (int i = 0; i < 3; ++i) {
    const float v = finite ? LinearToSrgb(AcesFilm(c[i] * exposure_scale)) : 0.0f;
    rgb[i] = static_cast<std::uint8_t>(fminf(fmaxf(v * 255.0f + 0.5f, 0.0f), 255.0f));
    if (position) position[i] = fminf(fmaxf(v * 255.0f, 0.0f), 255.0f);
  }
}

// The whole image, on the host; exposure in stops.
ImageRgb8 ToneMap(const ImageRgbF& image, float exposure);

}  // namespace cinevol

// Host tone mapping.
#include "core/tone_map.h"

#include <cmath>

namespace cinevol {

ImageRgb8 ToneMap(const ImageRgbF& image, float exposure) {
  ImageRgb8 out{image.width, image.height, std::vector<std::uint8_t>(image.pixels.size() * 3)};
  const float scale = std::exp2(exposure);
  for (std::size_t i = 0; i < image.pixels.size(); ++i) ToneMapPixel(image.pixels[i], scale, &out.bytes[3 * i]);
  return out;
}

}  // namespace cinevol

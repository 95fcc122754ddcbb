// Host tone mapping.
#include "core/tone_map.h"

#include <cmath>

#include "core/parallel_for.h"

namespace cinevol {

ImageRgb8 ToneMap(const ImageRgbF& image, float exposure) {
  ImageRgb8 out{image.width, image.height, std::vector<std::uint8_t>(image.pixels.size() * 3)};
  const float scale = std::exp2(exposure);
  // Rows on the shared pool: a 720p image is nearly 3 million powf, about 70 ms on one core (a still's or a movie
  // frame's encoding waited on it).
  constexpr std::int64_t kRowsAChunk = 16;
  ParallelFor(image.height, [&](std::int64_t y) {
    const std::size_t row = std::size_t(y) * std::size_t(image.width);
    for (std::size_t i = row; i < row + std::size_t(image.width); ++i) {
      ToneMapPixel(image.pixels[i], scale, &out.bytes[3 * i]);
    }
  }, 0, kRowsAChunk);
  return out;
}

}  // namespace cinevol

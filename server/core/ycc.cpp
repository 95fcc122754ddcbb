// YCbCr back to RGB on the host.
#include "core/ycc.h"

#include <algorithm>
#include <stdexcept>

namespace cinevol {

ImageRgb8 ToRgb(const ImageYcc8& image) {
  if (image.width <= 0 || image.height <= 0 || !image.data ||
      image.size < YccBytes(image.width, image.height, image.chroma)) {
    throw std::invalid_argument("YCbCr planes do not match their size");
  }
  const int bw = image.chroma == ChromaSubsampling::k444 ? 1 : 2;
  const int bh = image.chroma == ChromaSubsampling::k420 ? 2 : 1;
  const int chroma_width = image.PlaneWidth(1);
  const std::uint8_t *luma = image.Plane(0), *cb_plane = image.Plane(1), *cr_plane = image.Plane(2);
  ImageRgb8 out{image.width, image.height, std::vector<std::uint8_t>(std::size_t(image.width) * image.height * 3)};
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      const std::size_t c = std::size_t(y / bh) * chroma_width + x / bw;
      const int l = luma[std::size_t(y) * image.width + x];
      const int cb = cb_plane[c] - 128, cr = cr_plane[c] - 128;
      // jdcolor.c's ycc_rgb_convert: R and B round half up, G shifts once.
      const int r = l + ((YccFix(1.40200) * cr + kYccHalf) >> kYccShift);
      const int g = l + ((-YccFix(0.34414) * cb + kYccHalf - YccFix(0.71414) * cr) >> kYccShift);
      const int b = l + ((YccFix(1.77200) * cb + kYccHalf) >> kYccShift);
      std::uint8_t* p = &out.bytes[3 * (std::size_t(y) * image.width + x)];
      p[0] = std::uint8_t(std::clamp(r, 0, 255));
      p[1] = std::uint8_t(std::clamp(g, 0, 255));
      p[2] = std::uint8_t(std::clamp(b, 0, 255));
    }
  }
  return out;
}

}  // namespace cinevol

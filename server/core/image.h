// Images in host memory: linear HDR RGB for rendering and denoising, 8-bit
// sRGB for display and encoding. Rows run top to bottom.
#pragma once

#include <cstdint>
#include <vector>

#include "core/vec.h"

namespace cinevol {

struct ImageRgbF {
  int width = 0, height = 0;
  std::vector<Vec3f> pixels;  // width * height, linear RGB
};

struct ImageRgb8 {
  int width = 0, height = 0;
  std::vector<std::uint8_t> bytes;  // width * height * 3, sRGB
};

}  // namespace cinevol

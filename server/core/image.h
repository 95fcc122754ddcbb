// Images in host memory: linear HDR RGB for rendering and denoising, 8-bit
// sRGB for display and encoding, and planar YCbCr as the JPEG encoder takes
// it. Rows run top to bottom.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/hd.h"
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

// Chroma at full resolution (4:4:4), half width (4:2:2) or half width and
// height (4:2:0, the smallest files).
enum class ChromaSubsampling { k444, k422, k420 };

// The chroma planes' size for an image's size: odd sizes round up, the last
// chroma sample covering the edge pixel alone (as in libjpeg).
CINEVOL_HD int ChromaWidth(int width, ChromaSubsampling chroma) {
  return chroma == ChromaSubsampling::k444 ? width : (width + 1) / 2;
}
CINEVOL_HD int ChromaHeight(int height, ChromaSubsampling chroma) {
  return chroma == ChromaSubsampling::k420 ? (height + 1) / 2 : height;
}
// Bytes of the three planes together.
CINEVOL_HD std::size_t YccBytes(int width, int height, ChromaSubsampling chroma) {
  return std::size_t(width) * height + 2 * std::size_t(ChromaWidth(width, chroma)) * ChromaHeight(height, chroma);
}

// Planar 8-bit YCbCr (JFIF: BT.601, full range): Y at full size, then Cb, then
// Cr at the chroma planes' size, each tightly packed, one after another.
// `data` keeps the planes alive: frames share pinned buffers that the display
// reuses once no frame holds them (pipeline/display.h).
struct ImageYcc8 {
  int width = 0, height = 0;
  ChromaSubsampling chroma = ChromaSubsampling::k420;
  std::shared_ptr<const std::uint8_t> data;
  std::size_t size = 0;  // bytes behind data

  // plane 0: Y, 1: Cb, 2: Cr.
  int PlaneWidth(int plane) const { return plane == 0 ? width : ChromaWidth(width, chroma); }
  int PlaneHeight(int plane) const { return plane == 0 ? height : ChromaHeight(height, chroma); }
  const std::uint8_t* Plane(int plane) const {
    const std::size_t luma = std::size_t(width) * height;
    const std::size_t chroma_plane = std::size_t(PlaneWidth(1)) * PlaneHeight(1);
    return data.get() + (plane == 0 ? 0 : luma + (plane - 1) * chroma_plane);
  }
};

}  // namespace cinevol

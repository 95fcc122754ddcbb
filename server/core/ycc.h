// sRGB to JPEG's YCbCr (JFIF: BT.601, full range) with chroma downsampling,
// in libjpeg-turbo's integer arithmetic (jccolor.c, jcsample.c), so planes
// made here encode like the ones libjpeg makes from the same RGB image. Runs
// where the frame was rendered (pipeline/display.h); ToRgb is the host's way
// back.
#pragma once

#include <cstdint>

#include "core/hd.h"
#include "core/image.h"

namespace cinevol {

// libjpeg's fixed point: 16 fractional bits, constants rounded to nearest.
inline constexpr int kYccShift = 16;
CINEVOL_HD constexpr int YccFix(double x) { return int(x * (1 << kYccShift) + 0.5); }
inline constexpr int kYccHalf = 1 << (kYccShift - 1);
inline constexpr int kYccChromaOffset = 128 << kYccShift;

struct Ycc {
  int y, cb, cr;
};

// As rgb_ycc_convert: Y rounds half up; Cb and Cr round with half minus one
// ulp, so the largest output is 255, not 256.
CINEVOL_HD Ycc RgbToYcc(int r, int g, int b) {
  constexpr int kYr = YccFix(0.29900), kYg = YccFix(0.58700), kYb = YccFix(0.11400);
  constexpr int kCbR = YccFix(0.16874), kCbG = YccFix(0.33126), kHalfScale = YccFix(0.5);
  constexpr int kCrG = YccFix(0.41869), kCrB = YccFix(0.08131);
  Ycc out;
  out.y = (kYr * r + kYg * g + kYb * b + kYccHalf) >> kYccShift;
  out.cb = (-kCbR * r - kCbG * g + kHalfScale * b + kYccChromaOffset + kYccHalf - 1) >> kYccShift;
  out.cr = (kHalfScale * r - kCrG * g - kCrB * b + kYccChromaOffset + kYccHalf - 1) >> kYccShift;
  return out;
}

// Pointers to planes laid out as ImageYcc8 says, in the memory being written.
struct YccPlanes {
  std::uint8_t* y = nullptr;
  std::uint8_t* cb = nullptr;
  std::uint8_t* cr = nullptr;
  int width = 0, height = 0;
  ChromaSubsampling chroma = ChromaSubsampling::k420;

  static YccPlanes Of(std::uint8_t* data, int width, int height, ChromaSubsampling chroma) {
    const std::size_t chroma_plane = std::size_t(ChromaWidth(width, chroma)) * ChromaHeight(height, chroma);
    std::uint8_t* cb = data + std::size_t(width) * height;
    return {data, cb, cb + chroma_plane, width, height, chroma};
  }
  CINEVOL_HD int block_width() const { return chroma == ChromaSubsampling::k444 ? 1 : 2; }
  CINEVOL_HD int block_height() const { return chroma == ChromaSubsampling::k420 ? 2 : 1; }
};

// One chroma sample at (cx, cy) and the luma samples of the pixel block it
// covers; `rgb_at(x, y, rgb)` gives a pixel's 8-bit sRGB. Blocks past the
// right or bottom edge repeat the edge pixels (libjpeg's expand_right_edge and
// bottom padding). The average rounds with libjpeg's alternating bias
// (h2v1_downsample: 0, 1, 0, ...; h2v2_downsample: 1, 2, 1, ...) along each
// row, so half values round neither always up nor always down.
template <class RgbAt>
CINEVOL_HD void WriteYccBlock(const YccPlanes& out, int cx, int cy, const RgbAt& rgb_at) {
  const int bw = out.block_width(), bh = out.block_height();
  int cb_sum = 0, cr_sum = 0;
  for (int dy = 0; dy < bh; ++dy) {
    for (int dx = 0; dx < bw; ++dx) {
      const int x = cx * bw + dx, y = cy * bh + dy;
      const int sx = x < out.width ? x : out.width - 1, sy = y < out.height ? y : out.height - 1;
      std::uint8_t rgb[3];
      rgb_at(sx, sy, rgb);
      const Ycc ycc = RgbToYcc(rgb[0], rgb[1], rgb[2]);
      if (x == sx && y == sy) out.y[y * out.width + x] = std::uint8_t(ycc.y);
      cb_sum += ycc.cb;
      cr_sum += ycc.cr;
    }
  }
  const int samples = bw * bh;  // 1, 2 or 4
  const int bias = samples == 1 ? 0 : samples == 2 ? (cx & 1) : 1 + (cx & 1);
  const int shift = samples == 4 ? 2 : samples - 1;
  const int i = cy * ChromaWidth(out.width, out.chroma) + cx;
  out.cb[i] = std::uint8_t((cb_sum + bias) >> shift);
  out.cr[i] = std::uint8_t((cr_sum + bias) >> shift);
}

// Back to 8-bit sRGB as libjpeg's decoder converts (jdcolor.c), chroma
// repeated over the pixels it covers: for callers that need the displayed
// image itself (metrics), not its JPEG.
ImageRgb8 ToRgb(const ImageYcc8& image);

}  // namespace cinevol

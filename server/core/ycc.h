// sRGB to JPEG's YCbCr (JFIF: BT.601, full range) with chroma downsampling,
// in libjpeg-turbo's integer arithmetic (jccolor.c, jcsample.c), so planes
// made here encode like the ones libjpeg makes from the same RGB image. Runs
// where the frame was rendered (pipeline/display.h); ToRgb is the host's way
// back.
#pragma once

#include <cmath>
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

// The same conversion in floats, before any rounding: what the integer
// codes approximate.
struct YccExact {
  float y, cb, cr;
};
CINEVOL_HD YccExact RgbToYccExact(const float* rgb) {
  return {0.29900f * rgb[0] + 0.58700f * rgb[1] + 0.11400f * rgb[2],
          -0.16874f * rgb[0] - 0.33126f * rgb[1] + 0.5f * rgb[2] + 128.0f,
          0.5f * rgb[0] - 0.41869f * rgb[1] - 0.08131f * rgb[2] + 128.0f};
}

// A sample that showed `last` keeps it while its exact value is less than a
// whole code from it (FrameSettings::hold_codes): noise that straddles a
// rounding step no longer flips the code frame after frame.
CINEVOL_HD std::uint8_t HeldCode(float exact, std::uint8_t last, int code) {
  return fabsf(exact - float(last)) < 1.0f ? last : std::uint8_t(code);
}

// One chroma sample at (cx, cy) and the luma samples of the pixel block it
// covers; `rgb_at(x, y, rgb, position)` gives a pixel's 8-bit sRGB and,
// where `position` is not null, its values before rounding. Blocks past the
// right or bottom edge repeat the edge pixels (libjpeg's expand_right_edge and
// bottom padding). The average rounds with libjpeg's alternating bias
// (h2v1_downsample: 0, 1, 0, ...; h2v2_downsample: 1, 2, 1, ...) along each
// row, so half values round neither always up nor always down.
// `hold`: `out` holds the previous frame's planes, and each sample keeps its
// code where HeldCode says, computed from the values before rounding.
template <class RgbAt>
CINEVOL_HD void WriteYccBlock(const YccPlanes& out, int cx, int cy, const RgbAt& rgb_at, bool hold = false) {
  const int bw = out.block_width(), bh = out.block_height();
  int cb_sum = 0, cr_sum = 0;
  float cb_exact = 0.0f, cr_exact = 0.0f;
  for (int dy = 0; dy < bh; ++dy) {
    for (int dx = 0; dx < bw; ++dx) {
      const int x = cx * bw + dx, y = cy * bh + dy;
      const int sx = x < out.width ? x : out.width - 1, sy = y < out.height ? y : out.height - 1;
      std::uint8_t rgb[3];
      float position[3];
      rgb_at(sx, sy, rgb, hold ? position : nullptr);
      const Ycc ycc = RgbToYcc(rgb[0], rgb[1], rgb[2]);
      const YccExact exact = hold ? RgbToYccExact(position) : YccExact{};
      if (x == sx && y == sy) {
        std::uint8_t& luma = out.y[y * out.width + x];
        luma = hold ? HeldCode(exact.y, luma, ycc.y) : std::uint8_t(ycc.y);
      }
      cb_sum += ycc.cb;
      cr_sum += ycc.cr;
      cb_exact += exact.cb;
      cr_exact += exact.cr;
    }
  }
  const int samples = bw * bh;  // 1, 2 or 4
  const int bias = samples == 1 ? 0 : samples == 2 ? (cx & 1) : 1 + (cx & 1);
  const int shift = samples == 4 ? 2 : samples - 1;
  const int i = cy * ChromaWidth(out.width, out.chroma) + cx;
  const int cb = (cb_sum + bias) >> shift, cr = (cr_sum + bias) >> shift;
  out.cb[i] = hold ? HeldCode(cb_exact / float(samples), out.cb[i], cb) : std::uint8_t(cb);
  out.cr[i] = hold ? HeldCode(cr_exact / float(samples), out.cr[i], cr) : std::uint8_t(cr);
}

// Back to 8-bit sRGB as libjpeg's decoder converts (jdcolor.c), chroma
// repeated over the pixels it covers: for callers that need the displayed
// image itself (metrics), not its JPEG.
ImageRgb8 ToRgb(const ImageYcc8& image);

}  // namespace cinevol

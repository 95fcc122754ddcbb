// The display's tone map (core/tone_map.h: exposure, ACES fit, sRGB, 8 bits)
// on the CPU as a table: a channel's 8-bit code is the number of the 255
// steps at or below its scaled radiance, 8 comparisons instead of a powf (at
// 720p the powf was 28 ms of every moving CPU frame). The curve computed in
// floats is monotonic but for wobbles of a few ulps: of the 1.1e9 floats
// below saturation, 186 have a code one lower than a smaller float's (an
// exhaustive check on glibc 2.36's powf), in windows around 50 of the 255
// steps, the widest 48 ulps (near saturation, where the curve is flat). So
// each step keeps its window, and values inside it take the formula: the
// same codes as ToneMapPixel, bit for bit (tests/pipeline/display_test.cpp).
// Host only: a GPU evaluates the formula.
#pragma once

#include <cstdint>

#include "core/tone_map.h"
#include "core/vec.h"

namespace cinevol {

class ToneMapTable {
 public:
  // Built once, on first use (about 8,000 evaluations of the curve).
  static const ToneMapTable& Get();

  // What ToneMapPixel(c, exposure_scale, rgb, position) writes, the
  // positions within a tenth of a code (Position): a held code's edge moves
  // by no more.
  void Map(Vec3f c, float exposure_scale, std::uint8_t* rgb, float* position = nullptr) const {
    const bool finite = IsFinite(c);
    for (int i = 0; i < 3; ++i) {
      const float v = finite ? c[i] * exposure_scale : 0.0f;
      rgb[i] = Code(v);
      if (position) position[i] = Position(v, rgb[i]);
    }
  }

  std::uint8_t Code(float v) const {
    int code = 0;
    for (int step = 128; step > 0; step >>= 1) code = v >= first_[code + step] ? code + step : code;
    return v <= last_below_[code] ? Formula(v) : std::uint8_t(code);
  }
  // The least scaled radiance shown as `code` (1..255) or more.
  float step(int code) const { return first_[code]; }

  // DisplayPosition(v) for v of `code`: linear between the steps around it
  // (the curve is smooth within a step); the formula for the last code,
  // whose step has no upper end.
  float Position(float v, std::uint8_t code) const {
    if (code == 255) return DisplayPosition(v);
    const float lo = code == 0 ? 0.0f : first_[code], hi = first_[code + 1];
    const float t = fminf(fmaxf((v - lo) / (hi - lo), 0.0f), 1.0f);
    return code == 0 ? 0.5f * t : float(code) - 0.5f + t;
  }

  // How far from a step (bisection's crossing) the table looks for the
  // wobble: 5 times the widest window the exhaustive check found.
  static constexpr int kWobbleUlps = 256;

 private:
  ToneMapTable();
  static std::uint8_t Formula(float v);

  float first_[256];       // [k]: the least value with a code of k or more ([0] is never read)
  float last_below_[256];  // [k]: the greatest value with a code below k (-inf for k = 0)
};

// The tone map a CPU display runs: the table.
struct TableToneMap {
  const ToneMapTable* table;
  void operator()(Vec3f c, float exposure_scale, std::uint8_t* rgb, float* position) const {
    table->Map(c, exposure_scale, rgb, position);
  }
};

}  // namespace cinevol

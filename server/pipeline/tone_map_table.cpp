// ToneMapTable: each code's step and wobble window, by bisection over floats.
#include "pipeline/tone_map_table.h"

#include <algorithm>
#include <bit>
#include <cfloat>
#include <cmath>

#include "core/tone_map.h"

namespace cinevol {

std::uint8_t ToneMapTable::Formula(float v) {
  std::uint8_t rgb[3];
  ToneMapPixel(Vec3f{v, v, v}, 1.0f, rgb);
  return rgb[0];
}

ToneMapTable::ToneMapTable() {
  first_[0] = 0.0f;
  last_below_[0] = -INFINITY;
  for (int code = 1; code < 256; ++code) {
    // Positive floats order as their bits: bisect the bits for a value where
    // the code reaches `code` (Formula(0) is 0, Formula(FLT_MAX) 255) ...
    std::uint32_t lo = 0, hi = std::bit_cast<std::uint32_t>(FLT_MAX);  // Formula(lo) < code <= Formula(hi)
    while (hi - lo > 1) {
      const std::uint32_t mid = lo + (hi - lo) / 2;
      (Formula(std::bit_cast<float>(mid)) >= code ? hi : lo) = mid;
    }
    // ... then find the wobble around it: the least value at `code` or more,
    // and the greatest below it.
    std::uint32_t first = hi, last_below = lo;
    const std::uint32_t from = hi > kWobbleUlps ? hi - kWobbleUlps : 0, to = hi + kWobbleUlps;
    for (std::uint32_t b = from; b <= to; ++b) {
      if (Formula(std::bit_cast<float>(b)) >= code) {
        first = std::min(first, b);
      } else {
        last_below = std::max(last_below, b);
      }
    }
    first_[code] = std::bit_cast<float>(first);
    last_below_[code] = std::bit_cast<float>(last_below);
  }
}

const ToneMapTable& ToneMapTable::Get() {
  static const ToneMapTable table;
  return table;
}

}  // namespace cinevol

// Passes with a CPU form of their own: the same per-pixel maths as their
// functors, laid out in rows the compiler vectorises. Here, the a-trous
// levels' (AtrousTaps, baselines.h): SVGF's and wRLS's (cpu_atrous.cpp) and
// the refinement's (pipeline/cpu_refine.cpp). RunAtrousLevel calls these on
// CpuBackend and launches the functors per pixel elsewhere.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>
#include <vector>

#include "core/parallel_for.h"
#include "core/vec.h"

namespace cinevol {

// e^x within 2 ulp for x in [-87.3, 88.3], 0 below, +inf above, NaN for
// NaN (Cephes' expf: x = n ln2 + r, |r| <= ln2 / 2, a degree-7 polynomial
// in r, times 2^n built in the exponent bits). Branch-free, so it
// vectorises.
inline float VectorisableExp(float x) {
  constexpr float kLog2e = 1.44269504088896341f, kLn2Hi = 0.693359375f, kLn2Lo = -2.12194440e-4f;
  constexpr float kRound = 12582912.0f;  // 1.5 * 2^23: adding it rounds to an integer
  float n = (x * kLog2e + kRound) - kRound;
  n = !(n >= -126.0f) ? -126.0f : (n > 127.0f ? 127.0f : n);  // NaN too: the polynomial carries it
  const float r = (x - n * kLn2Hi) - n * kLn2Lo;
  float p = 1.9875691500e-4f;
  p = p * r + 1.3981999507e-3f;
  p = p * r + 8.3334519073e-3f;
  p = p * r + 4.1665795894e-2f;
  p = p * r + 1.6666665459e-1f;
  p = p * r + 5.0000001201e-1f;
  p = p * (r * r) + r + 1.0f;
  const std::int32_t bits = (static_cast<std::int32_t>(n) + 127) << 23;
  float scale;
  std::memcpy(&scale, &bits, sizeof scale);
  const float e = p * scale;
  return x < -87.33654f ? 0.0f : (x > 88.37626f ? INFINITY : e);
}

// `count` (at most 14) planes of n floats, this thread's, kept between calls
// (levels, frames): calls from several threads (sessions) each have their
// own. Pass the pointer on: the helpers' own thread_local would be another.
inline std::vector<float>* ThreadPlanes(int count, std::size_t n) {
  thread_local std::vector<float> planes[14];
  for (int k = 0; k < count; ++k) planes[k].resize(n);
  return planes;
}

// A level's colour and variance, one plane each.
struct ColourPlanes {
  const float *r, *g, *b, *v;
  ColourPlanes Offset(std::ptrdiff_t i) const { return {r + i, g + i, b + i, v + i}; }
};

// The sums of one row's taps, one plane each: colour and variance (with the
// squared weights) weighted, and the weights.
struct AtrousRowSums {
  float *r, *g, *b, *v, *w;
};

// One tap (dx, dy) * step for one row: pixels [x0, x1) of the row that
// starts at index `row`, whose neighbours (all inside the frame) start at
// `neighbour_row`.
struct AtrousRowTap {
  std::ptrdiff_t row, neighbour_row;
  int x0, x1;
  float kernel_weight;
};

// Adds a tap to a row's sums, each pixel's neighbour weighed
// kernel_weight * e^exponent(x). Inlined into a row kernel built for AVX2
// and the baseline x86-64 (target_clones), where it vectorises.
template <class Exponent>
inline void AddAtrousTap(const ColourPlanes& colour, AtrousRowSums s, const AtrousRowTap& tap,
                         const Exponent& exponent) {
  const ColourPlanes neighbour = colour.Offset(tap.neighbour_row);
  // The planes and sums never overlap; GCC does not take __restrict on
  // locals, and 10 run-time alias checks are its limit.
#pragma GCC ivdep
  for (int x = tap.x0; x < tap.x1; ++x) {
    const float w = tap.kernel_weight * VectorisableExp(exponent(x));
    s.r[x] += neighbour.r[x] * w;
    s.g[x] += neighbour.g[x] * w;
    s.b[x] += neighbour.b[x] * w;
    s.v[x] += neighbour.v[x] * w * w;
    s.w[x] += w;
  }
}

// One a-trous level over the frame, as AtrousTaps takes its taps but a row
// at a time: add_tap(sums, tap) adds each tap inside the frame to the row's
// sums; then the row's colour and variance are written to `out`.
template <class AddTap>
void CpuAtrousRows(int width, int height, int step, Vec4f* out, const AddTap& add_tap) {
  ParallelFor(height, [&](std::int64_t yy) {
    const int y = int(yy);
    thread_local std::vector<float> sums;
    sums.assign(std::size_t(5) * width, 0.0f);
    const AtrousRowSums s{sums.data(), sums.data() + width, sums.data() + 2 * width, sums.data() + 3 * width,
                          sums.data() + 4 * width};
    const float kernel[3] = {3.0f / 8.0f, 1.0f / 4.0f, 1.0f / 16.0f};
    for (int dy = -2; dy <= 2; ++dy) {
      const int ny = y + dy * step;
      if (ny < 0 || ny >= height) continue;
      for (int dx = -2; dx <= 2; ++dx) {
        const int shift = dx * step;
        const int x0 = MaxInt(0, -shift), x1 = MinInt(width, width - shift);
        if (x0 >= x1) continue;
        add_tap(s, AtrousRowTap{std::ptrdiff_t(y) * width, std::ptrdiff_t(ny) * width + shift, x0, x1,
                                kernel[dx < 0 ? -dx : dx] * kernel[dy < 0 ? -dy : dy]});
      }
    }
    for (int x = 0; x < width; ++x) {
      const Vec3f sum{s.r[x], s.g[x], s.b[x]};
      const float weight = s.w[x];
      out[y * width + x] = ToVec4(sum / weight, s.v[x] / (weight * weight));
    }
  });
}

struct AtrousPass;
struct CpuBackend;

// One a-trous level: AtrousPass over the whole frame (cpu_atrous.cpp). The
// refinement's MeanFilterPass has its overload (pipeline/cpu_refine.cpp).
void CpuAtrousLevel(const AtrousPass& pass);

// One a-trous level on backend B: on the CPU as rows of the same weights,
// elsewhere the functor per pixel.
template <class B, class Pass>
void RunAtrousLevel(const Pass& pass) {
  if constexpr (std::is_same_v<B, CpuBackend>) {
    CpuAtrousLevel(pass);
  } else {
    B::ForEachPixel(pass.width, pass.height, pass);
  }
}

}  // namespace cinevol

// Denoiser passes with a CPU form of their own: the same per-pixel maths as
// their functors (baselines.h), laid out in rows the compiler vectorises.
// The drivers (denoisers.h) call these on CpuBackend and launch the functors
// per pixel elsewhere.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>

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

struct AtrousPass;

// One a-trous level: AtrousPass over the whole frame (cpu_atrous.cpp).
void CpuAtrousLevel(const AtrousPass& pass);

}  // namespace cinevol

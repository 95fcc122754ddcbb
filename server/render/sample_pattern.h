// Stratified 2D samples for the pixel filter and the lens: Kensler's
// correlated multi-jittered sampling ("Correlated Multi-Jittered Sampling",
// Pixar 2013), stratified in 2D and in each axis for any sample count. A
// pattern id (hash of seed, frame and pixel) gives each pixel and frame its
// own pattern.
#pragma once

#include <cstdint>

#include "core/hd.h"
#include "core/vec.h"

namespace cinevol {

// A pseudo-random permutation of [0, n) applied to i; pattern p picks which.
CINEVOL_HD std::uint32_t Permute(std::uint32_t i, std::uint32_t n, std::uint32_t p) {
  std::uint32_t w = n - 1;
  w |= w >> 1;
  w |= w >> 2;
  w |= w >> 4;
  w |= w >> 8;
  w |= w >> 16;
  do {  // cycle-walking: under two rounds on average
    i ^= p;
    i *= 0xe170893dU;
    i ^= p >> 16;
    i ^= (i & w) >> 4;
    i ^= p >> 8;
    i *= 0x0929eb3fU;
    i ^= p >> 23;
    i ^= (i & w) >> 1;
    i *= 1 | p >> 27;
    i *= 0x6935fa69U;
    i ^= (i & w) >> 11;
    i *= 0x74dcb303U;
    i ^= (i & w) >> 2;
    i *= 0x9e501cc3U;
    i ^= (i & w) >> 2;
    i *= 0xc860a3dfU;
    i &= w;
    i ^= i >> 5;
  } while (i >= n);
  return (i + p) % n;
}

CINEVOL_HD float HashToFloat(std::uint32_t i, std::uint32_t p) {
  i ^= p;
  i ^= i >> 17;
  i ^= i >> 10;
  i *= 0xb36534e5U;
  i ^= i >> 12;
  i ^= i >> 21;
  i *= 0x93fc4795U;
  i ^= 0xdf6e307fU;
  i ^= i >> 17;
  i *= 1 | p >> 18;
  return static_cast<float>(i >> 8) * 0x1p-24f;
}

// Sample s of n in [0,1)^2 for pattern p.
CINEVOL_HD void CorrelatedMultiJitter(std::uint32_t s, std::uint32_t n, std::uint32_t p, float& u,
                                      float& v) {
  const std::uint32_t m = MaxInt(1, static_cast<int>(sqrtf(float(n))));
  const std::uint32_t k = (n + m - 1) / m;
  s = Permute(s, n, p * 0x51633e2dU);
  const std::uint32_t sx = Permute(s % m, m, p * 0x68bc21ebU);
  const std::uint32_t sy = Permute(s / m, k, p * 0x02e5be93U);
  const float jx = HashToFloat(s, p * 0x967a889bU);
  const float jy = HashToFloat(s, p * 0x368cc8b7U);
  u = (float(sx) + (float(sy) + jx) / float(k)) / float(m);
  v = (float(s) + jy) / float(n);
  u = u < 1.0f ? u : 0x1.fffffep-1f;
}

}  // namespace cinevol

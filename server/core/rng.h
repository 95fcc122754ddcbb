// Random numbers for host and device: PCG32 streams seeded by hashing
// (seed, frame, pixel), so every pixel's samples are the same whichever thread
// or GPU block draws them.
#pragma once

#include <cstdint>

#include "core/hd.h"

namespace cinevol {

// A 64-bit mix (splitmix64 finaliser) for seeding.
CINEVOL_HD std::uint64_t MixBits(std::uint64_t v) {
  v ^= v >> 31;
  v *= 0x7fb5d329728ea185ULL;
  v ^= v >> 27;
  v *= 0x81dadef4bc2dd44dULL;
  v ^= v >> 33;
  return v;
}

CINEVOL_HD std::uint64_t HashCombine(std::uint64_t a, std::uint64_t b) {
  return MixBits(a ^ (b + 0x9e3779b97f4a7c15ULL + (a << 6) + (a >> 2)));
}

// PCG32 (O'Neill 2014): 64-bit state, 32-bit output, selectable stream.
class Pcg32 {
 public:
  CINEVOL_HD Pcg32(std::uint64_t seed, std::uint64_t stream) : state_(0), inc_((stream << 1u) | 1u) {
    NextUInt();
    state_ += seed;
    NextUInt();
  }

  CINEVOL_HD std::uint32_t NextUInt() {
    const std::uint64_t old = state_;
    state_ = old * 0x5851f42d4c957f2dULL + inc_;
    const std::uint32_t xorshifted = static_cast<std::uint32_t>(((old >> 18u) ^ old) >> 27u);
    const std::uint32_t rot = static_cast<std::uint32_t>(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((32u - rot) & 31u));
  }

  // Uniform in [0, 1): 24 random bits, so 1 - u is never 0.
  CINEVOL_HD float Uniform() { return static_cast<float>(NextUInt() >> 8) * 0x1p-24f; }

 private:
  std::uint64_t state_;
  std::uint64_t inc_;
};

}  // namespace cinevol

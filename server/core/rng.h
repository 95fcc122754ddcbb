// Random numbers for host and device: PCG32 streams seeded by hashing
// (seed, frame, pixel), so every pixel's samples are the same whichever thread
// or GPU block draws them.
#pragma once

#include <cstdint>
#include <cstring>

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

// PCG32 (O'Neill 2014) in its 32-bit form, RXS-M-XS: 32-bit state and output,
// one stream per odd increment. The path tracer draws a number per tentative
// collision, so its generator is on the hot path: the 64-bit PCG32 took
// about fifteen instructions a draw (Nsight Compute's listing) and four
// registers of state, this one half the state and 32-bit arithmetic only
// (docs/performance.md). A stream repeats after 2^32 draws; a path draws at
// most about 2^17 (kMaxPathCollisions).
class Pcg32 {
 public:
  // The state from the seed, the increment from the stream and the seed's
  // high half: neighbouring pixels then run different sequences, not one
  // sequence from different starts.
  CINEVOL_HD Pcg32(std::uint64_t seed, std::uint64_t stream)
      : state_(static_cast<std::uint32_t>(seed ^ (seed >> 32))),
        inc_(static_cast<std::uint32_t>(MixBits(stream ^ (seed & 0xffffffff00000000ULL)) << 1u) | 1u) {
    NextUInt();
  }

  CINEVOL_HD std::uint32_t NextUInt() {
    const std::uint32_t old = state_;
    state_ = old * 747796405u + inc_;
    const std::uint32_t word = ((old >> ((old >> 28u) + 4u)) ^ old) * 277803737u;
    return (word >> 22u) ^ word;
  }

  // Uniform in [0, 1): 23 random bits as the mantissa of a float in [1, 2),
  // less 1 (a shift, a bitwise or and an addition; an integer-to-float
  // conversion runs at a quarter of the GPU's float rate), so 1 - u is never 0.
  CINEVOL_HD float Uniform() {
    const std::uint32_t bits = (NextUInt() >> 9) | 0x3f800000u;
    float one_to_two;
    std::memcpy(&one_to_two, &bits, sizeof one_to_two);
    return one_to_two - 1.0f;
  }

 private:
  std::uint32_t state_;
  std::uint32_t inc_;
};

}  // namespace cinevol

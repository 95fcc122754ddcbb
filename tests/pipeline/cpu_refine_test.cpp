// The CPU's row form of the refinement's filter level (pipeline/cpu_refine.cpp)
// against the per-pixel functor the GPU runs.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "core/rng.h"
#include "device/cpu_backend.h"
#include "pipeline/refine.h"
#include "support/functor_and_rows.h"

namespace cinevol {
namespace {

std::vector<Vec4f> NoisyMean(int width, int height) {
  std::vector<Vec4f> image;
  Pcg32 rng(5, 9);
  for (int i = 0; i < width * height; ++i) {
    const float v = (i % width < width / 2 ? 0.8f : 0.05f) * (0.5f + rng.Uniform());
    image.push_back({v, 0.9f * v, 0.7f * v, 0.01f * rng.Uniform()});
  }
  return image;
}

TEST(CpuMeanFilterLevel, AgreesWithThePerPixelPass) {
  const int width = 41, height = 29;
  for (const int step : {1, 2, 4}) {
    std::vector<Vec4f> in = NoisyMean(width, height);
    testing::ExpectRowsAgree(
        testing::FunctorAndRows(MeanFilterPass{in.data(), nullptr, width, height, step, kDarkGrey}),
        "step " + std::to_string(step));
  }
}

TEST(CpuMeanFilterLevel, TakesTheLargestChannelDifferenceAsFmaxfDoes) {
  const int width = 9, height = 7;
  std::vector<Vec4f> in = NoisyMean(width, height);
  in[3 * width + 4].y = std::numeric_limits<float>::quiet_NaN();  // fmaxf passes over a NaN difference
  testing::ExpectRowsAgree(testing::FunctorAndRows(MeanFilterPass{in.data(), nullptr, width, height, 1, kDarkGrey}),
                           "NaN in one channel");
}

}  // namespace
}  // namespace cinevol

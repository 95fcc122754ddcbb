// The CPU's row form of the refinement's filter level (pipeline/cpu_refine.cpp)
// against the per-pixel functor the GPU runs.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "core/rng.h"
#include "device/cpu_backend.h"
#include "pipeline/refine.h"

namespace cinevol {
namespace {

float Component(const Vec4f& v, int c) { return c == 0 ? v.x : c == 1 ? v.y : c == 2 ? v.z : v.w; }

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
    std::vector<Vec4f> in = NoisyMean(width, height), functor(in.size()), rows(in.size());
    const MeanFilterPass pass{in.data(), functor.data(), width, height, step, kDarkGrey};
    CpuBackend::ForEachPixel(width, height, pass);
    MeanFilterPass row_pass = pass;
    row_pass.out = rows.data();
    CpuAtrousLevel(row_pass);
    for (std::size_t i = 0; i < rows.size(); ++i) {
      for (int c = 0; c < 4; ++c) {
        const float expected = Component(functor[i], c);
        EXPECT_NEAR(Component(rows[i], c), expected, 2e-6f * std::fabs(expected) + 1e-12f)
            << "pixel " << i << " channel " << c << " step " << step;
      }
    }
  }
}

TEST(CpuMeanFilterLevel, TakesTheLargestChannelDifferenceAsFmaxfDoes) {
  const int width = 9, height = 7;
  std::vector<Vec4f> in = NoisyMean(width, height), functor(in.size()), rows(in.size());
  in[3 * width + 4].y = std::numeric_limits<float>::quiet_NaN();  // fmaxf passes over a NaN difference
  const MeanFilterPass pass{in.data(), functor.data(), width, height, 1, kDarkGrey};
  CpuBackend::ForEachPixel(width, height, pass);
  MeanFilterPass row_pass = pass;
  row_pass.out = rows.data();
  CpuAtrousLevel(row_pass);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    for (int c = 0; c < 4; ++c) {
      const float expected = Component(functor[i], c), got = Component(rows[i], c);
      EXPECT_EQ(std::isnan(got), std::isnan(expected)) << "pixel " << i << " channel " << c;
      if (!std::isnan(expected)) {
        EXPECT_NEAR(got, expected, 2e-6f * std::fabs(expected) + 1e-12f);
      }
    }
  }
}

}  // namespace
}  // namespace cinevol

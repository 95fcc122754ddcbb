// An a-trous level run both ways, for the tests of the CPU's row kernels
// (denoise/cpu_atrous.cpp, pipeline/cpu_refine.cpp): the per-pixel functor
// the GPU runs, and CpuAtrousLevel's rows, over the same input.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "core/vec.h"
#include "device/cpu_backend.h"

namespace cinevol::testing {

inline float Component(const Vec4f& v, int c) { return c == 0 ? v.x : c == 1 ? v.y : c == 2 ? v.z : v.w; }

// The functor's output and the rows' output of `pass` (its `out` is
// replaced). CpuAtrousLevel has an overload per pass.
template <class Pass>
std::pair<std::vector<Vec4f>, std::vector<Vec4f>> FunctorAndRows(Pass pass) {
  const std::size_t n = std::size_t(pass.width) * pass.height;
  std::vector<Vec4f> functor(n), rows(n);
  pass.out = functor.data();
  CpuBackend::ForEachPixel(pass.width, pass.height, pass);
  pass.out = rows.data();
  CpuAtrousLevel(pass);
  return {std::move(functor), std::move(rows)};
}

// Every channel the same within 2e-6 (the rows' exp is within 2 ulp), and
// NaN where the functor's is.
inline void ExpectRowsAgree(const std::pair<std::vector<Vec4f>, std::vector<Vec4f>>& outputs,
                            const std::string& what) {
  const auto& [functor, rows] = outputs;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    for (int c = 0; c < 4; ++c) {
      const float expected = Component(functor[i], c), got = Component(rows[i], c);
      EXPECT_EQ(std::isnan(got), std::isnan(expected)) << what << ": pixel " << i << " channel " << c;
      if (!std::isnan(expected)) {
        EXPECT_NEAR(got, expected, 2e-6f * std::fabs(expected) + 1e-12f) << what << ": pixel " << i << " channel " << c;
      }
    }
  }
}

}  // namespace cinevol::testing

// The CPU's row form of an a-trous level (denoise/cpu_atrous.cpp) against
// the per-pixel functor the GPU runs: the same weights, the same sums, with
// e^x evaluated by a vectorisable exp within 2 ulp of the exact value.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/rng.h"
#include "denoise/baselines.h"
#include "device/cpu_backend.h"
#include "denoise/cpu_passes.h"
#include "support/functor_and_rows.h"

namespace cinevol {
namespace {

// Units in the last place between a float and the exact value.
double Ulps(float value, double exact) {
  const double ulp = std::nextafter(float(exact), std::numeric_limits<float>::infinity()) - float(exact);
  return std::fabs(double(value) - exact) / ulp;
}

TEST(VectorisableExp, IsWithinTwoUlpsOverTheWeightsRange) {
  double worst = 0;
  for (float x = -87.0f; x <= 88.0f; x += 0.000731f)
    worst = std::max(worst, Ulps(VectorisableExp(x), std::exp(double(x))));
  EXPECT_LE(worst, 2.0);
  EXPECT_EQ(VectorisableExp(0.0f), 1.0f);
}

TEST(VectorisableExp, KeepsTheEdgeCasesOfExpf) {
  EXPECT_EQ(VectorisableExp(-std::numeric_limits<float>::infinity()), 0.0f);
  EXPECT_EQ(VectorisableExp(-1e30f), 0.0f);
  EXPECT_EQ(VectorisableExp(-100.0f), 0.0f) << "below the normal range: 0 (expf gives a subnormal)";
  EXPECT_TRUE(std::isinf(VectorisableExp(100.0f)));
  EXPECT_TRUE(std::isnan(VectorisableExp(std::numeric_limits<float>::quiet_NaN())));
}

struct Frame {
  int width, height;
  std::vector<Vec4f> image, first_hit;
  std::vector<EdgeGuide> guides;
  Camera camera;
  std::vector<Vec3f> normals;  // surface probability times normal; 0 where escaped
};

// Noisy radiance over a silhouette, with escaped pixels, a band of depths
// and odd sizes (the taps' clipping at every edge).
Frame NoisyFrame(int width, int height) {
  const std::size_t n = std::size_t(width) * height;
  Frame f{width, height, {}, {}, std::vector<EdgeGuide>(n), {}, {}};
  f.camera = LookAt({0, -300, 0}, {0, 0, 0}, {0, 0, 1}, 30, width, height);
  Pcg32 rng(11, 3);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const bool hit = x < width * 2 / 3 && rng.Uniform() < 0.9f;
      const float v = (hit ? 1.0f : 0.3f) * (0.5f + rng.Uniform());
      f.image.push_back({v, 0.8f * v, 0.6f * v, 0.05f * rng.Uniform()});
      f.first_hit.push_back(hit ? Vec4f{20.0f * rng.Uniform(), float(y), float(x), 1} : Vec4f{});
      const Vec3f n = Normalize(Vec3f{rng.Uniform() - 0.5f, -1.0f, rng.Uniform() - 0.5f});
      f.normals.push_back(hit ? n * rng.Uniform() : Vec3f{});
    }
  }
  std::vector<float> row_hits(n);
  ComputeEdgeGuides<CpuBackend>(f.first_hit.data(), f.camera.eye, width, height, row_hits.data(), f.guides.data());
  return f;
}

TEST(CpuAtrousLevel, AgreesWithThePerPixelPass) {
  for (const bool squared : {false, true}) {
    for (const int step : {1, 2, 4, 8, 16}) {
      Frame f = NoisyFrame(97, 83);  // each step has pixels away from the edges
      testing::ExpectRowsAgree(testing::FunctorAndRows(AtrousPass{f.image.data(), nullptr, f.guides.data(), f.width,
                                                                  f.height, step, 4.0f, 8.0f, squared}),
                               "step " + std::to_string(step) + (squared ? " squared" : ""));
    }
  }
}

TEST(CpuAtrousLevel, AgreesWithThePerPixelPassWithANormalStop) {
  for (const bool squared : {false, true}) {
    for (const int step : {1, 4}) {
      Frame f = NoisyFrame(97, 83);
      AtrousPass pass{f.image.data(), nullptr, f.guides.data(), f.width, f.height, step, 4.0f, 8.0f, squared};
      pass.normals = f.normals.data();
      pass.normal_stop = 16.0f;
      testing::ExpectRowsAgree(testing::FunctorAndRows(pass),
                               "normals, step " + std::to_string(step) + (squared ? " squared" : ""));
    }
  }
}

TEST(CpuAtrousLevel, CarriesANonFiniteInputAsThePassDoes) {
  Frame f = NoisyFrame(20, 12);
  f.image[5 * 20 + 7].x = std::numeric_limits<float>::quiet_NaN();
  testing::ExpectRowsAgree(
      testing::FunctorAndRows(AtrousPass{f.image.data(), nullptr, f.guides.data(), 20, 12, 1, 4.0f, 8.0f}), "NaN");
}

}  // namespace
}  // namespace cinevol

// The a-trous levels SVGF and wRLS share, in isolation: the coverage edge
// stop must mix semi-transparent tissue (whose pixels hit or escape at
// random) and still stop at a real silhouette.
#include <gtest/gtest.h>

#include <cmath>
#include <utility>
#include <vector>

#include "core/camera.h"
#include "core/rng.h"
#include "device/cpu_backend.h"
#include "denoise/baselines.h"

namespace cinevol {
namespace {

constexpr int kSize = 48;

// Five levels (steps 1..16) over `image` (rgb, w variance) with the
// settings wRLS uses (the luminance stop squared if asked).
// `normals`: with a normal stop of 16 at them (AtrousPass::normals).
std::vector<Vec4f> Atrous(std::vector<Vec4f> image, const std::vector<Vec4f>& first_hit, bool squared = false,
                          const std::vector<Vec3f>* normals = nullptr) {
  const Camera camera = LookAt({0, -300, 0}, {0, 0, 0}, {0, 0, 1}, 30, kSize, kSize);
  std::vector<EdgeGuide> guides(image.size());
  std::vector<float> row_hits(image.size());
  ComputeEdgeGuides<CpuBackend>(first_hit.data(), camera.eye, kSize, kSize, row_hits.data(), guides.data());
  std::vector<Vec4f> out(image.size());
  for (int level = 0; level < 5; ++level) {
    CpuBackend::ForEachPixel(kSize, kSize,
                             AtrousPass{image.data(), out.data(), guides.data(), kSize, kSize, 1 << level, 4.0f, 8.0f,
                                        squared, nullptr, normals ? normals->data() : nullptr, 16.0f});
    image.swap(out);
  }
  return image;
}

Vec4f Grey(float value, float variance) { return {value, value, value, variance}; }

// Half the pixels' samples hit a shell (radiance 1), the others escape to a
// background of 0.5, at random: the pixel's value is 0.75 either way.
TEST(Atrous, MixesHitAndEscapedPixelsOfTransparentTissue) {
  std::vector<Vec4f> image, first_hit;
  Pcg32 rng(7, 1);
  for (int i = 0; i < kSize * kSize; ++i) {
    const bool hit = rng.Uniform() < 0.5f;
    image.push_back(Grey(hit ? 1.0f : 0.5f, 0.0625f));
    first_hit.push_back(hit ? Vec4f{0, 0, 0, 1} : Vec4f{0, 0, 0, 0});
  }
  const std::vector<Vec4f> out = Atrous(image, first_hit);
  double sum = 0, sum_sq = 0;
  int n = 0;
  for (int y = 8; y < kSize - 8; ++y) {
    for (int x = 8; x < kSize - 8; ++x) {
      const double v = out[y * kSize + x].x;
      sum += v;
      sum_sq += v * v;
      ++n;
    }
  }
  const double mean = sum / n, deviation = std::sqrt(std::max(sum_sq / n - mean * mean, 0.0));
  EXPECT_NEAR(mean, 0.75, 0.05);
  EXPECT_LT(deviation, 0.05) << "hit and escaped pixels stayed apart (input deviation 0.25)";
}

// Opaque tissue (radiance 1) on the left, a lit background (0.4) on the
// right, both noisy enough that the luminance stop alone would let them mix:
// coverage keeps them apart.
TEST(Atrous, StopsAtASilhouette) {
  std::vector<Vec4f> image, first_hit;
  for (int y = 0; y < kSize; ++y) {
    for (int x = 0; x < kSize; ++x) {
      const bool hit = x < kSize / 2;
      image.push_back(hit ? Grey(1.0f, 0.1f) : Grey(0.4f, 0.1f));
      first_hit.push_back(hit ? Vec4f{0, 0, 0, 1} : Vec4f{0, 0, 0, 0});
    }
  }
  const std::vector<Vec4f> out = Atrous(image, first_hit);
  // Two pixels in from the edge (the luminance stop alone leaves 0.965 and
  // 0.435 there).
  for (int y = 0; y < kSize; ++y) {
    EXPECT_GT(out[y * kSize + kSize / 2 - 2].x, 0.985f) << "tissue darkened at row " << y;
    EXPECT_LT(out[y * kSize + kSize / 2 + 1].x, 0.415f) << "background brightened at row " << y;
  }
}

// One opaque surface (no silhouette), its left half 1 and its right half
// 1.6, each pixel with noise of deviation 0.1: a step of 6 deviations. The
// squared luminance stop blurs the step less than SVGF's (0.015 against
// 0.022 off the clean step beside it), for a little more noise left on the
// flat halves (0.0063 against 0.0050): a trade, as a smaller sigma is.
TEST(Atrous, SquaredLuminanceStopKeepsAStepSharper) {
  std::vector<Vec4f> image, first_hit;
  Pcg32 rng(5, 2);
  for (int y = 0; y < kSize; ++y) {
    for (int x = 0; x < kSize; ++x) {
      const float level = x < kSize / 2 ? 1.0f : 1.6f;
      image.push_back(Grey(level + 0.3464f * (rng.Uniform() - 0.5f), 0.01f));  // uniform, deviation 0.1
      first_hit.push_back({0, 0, 0, 1});
    }
  }
  // Mean absolute error against the clean step next to it (the two columns
  // each side) and away from it (columns 8 to 15).
  const auto errors = [&](const std::vector<Vec4f>& out) {
    double near = 0, flat = 0;
    for (int y = 8; y < kSize - 8; ++y) {
      for (int x = kSize / 2 - 2; x < kSize / 2 + 2; ++x) {
        near += std::fabs(out[y * kSize + x].x - (x < kSize / 2 ? 1.0 : 1.6));
      }
      for (int x = 8; x < 16; ++x) flat += std::fabs(out[y * kSize + x].x - 1.0);
    }
    return std::pair{near / (4 * (kSize - 16)), flat / (8 * (kSize - 16))};
  };
  const auto [svgf_step, svgf_flat] = errors(Atrous(image, first_hit));
  const auto [squared_step, squared_flat] = errors(Atrous(image, first_hit, true));
  EXPECT_LT(squared_step, 0.7 * svgf_step) << "the step blurred as much as with SVGF's stop";
  EXPECT_LT(squared_flat, 1.5 * svgf_flat) << "the flat halves kept much more noise";
  EXPECT_LT(squared_flat, 0.01) << "input noise 0.087 on average";
}

// One opaque surface folded along its middle (no silhouette, one depth): its
// left half faces the eye, its right half turns 60 degrees away and is lit
// 1.3 times as bright, each pixel with noise of deviation 0.1, so the
// luminance stop alone mixes the halves. The normal stop keeps the fold; where
// the renderer saw no surface (normals of length 0) it changes nothing.
TEST(Atrous, NormalStopKeepsAFoldBetweenSurfaces) {
  std::vector<Vec4f> image, first_hit;
  std::vector<Vec3f> folded, none(kSize * kSize);
  Pcg32 rng(5, 3);
  for (int y = 0; y < kSize; ++y) {
    for (int x = 0; x < kSize; ++x) {
      const bool left = x < kSize / 2;
      image.push_back(Grey((left ? 1.0f : 1.3f) + 0.3464f * (rng.Uniform() - 0.5f), 0.01f));
      first_hit.push_back({0, 0, 0, 1});
      folded.push_back(left ? Vec3f{0, -1, 0} : Vec3f{0.866f, -0.5f, 0});
    }
  }
  const auto fold_error = [&](const std::vector<Vec4f>& out) {
    double error = 0;
    for (int y = 8; y < kSize - 8; ++y) {
      for (int x = kSize / 2 - 2; x < kSize / 2 + 2; ++x) {
        error += std::fabs(out[y * kSize + x].x - (x < kSize / 2 ? 1.0 : 1.3));
      }
    }
    return error / (4 * (kSize - 16));
  };
  const std::vector<Vec4f> plain = Atrous(image, first_hit);
  EXPECT_LT(fold_error(Atrous(image, first_hit, false, &folded)), 0.5 * fold_error(plain))
      << "the fold blurred as much as without normals";
  const std::vector<Vec4f> unseen = Atrous(image, first_hit, false, &none);
  for (std::size_t i = 0; i < plain.size(); ++i) {
    ASSERT_TRUE(unseen[i].x == plain[i].x && unseen[i].w == plain[i].w)
        << "no surface seen, yet the normals changed pixel " << i;
  }
}

// The calibration's scale for `image`; `previous` > 0: the previous frame's,
// which the scale may fall from only to `fall` times it.
float Calibration(const std::vector<Vec4f>& image, const std::vector<EdgeGuide>& guides, float floor = 1e-3f,
                  float previous = 0.0f, float fall = 0.0f) {
  unsigned bins[kCalibrationBins];
  CpuBackend::CountInBins<kCalibrationBins>(kSize, CalibrationRows(kSize),
                                            StopCalibrationBin{image.data(), guides.data(), kSize}, bins);
  float scale = previous;
  StopCalibrationPass{bins, &scale, floor, fall, !(previous > 0.0f)}(0, 0);
  return scale;
}

// The frame's calibration of the luminance stop (StopCalibrationPass):
// noise of a known deviation, told its variance right, four times too large
// and ten times too small; pixels that escaped or are not finite are not
// measured.
TEST(StopCalibration, ReadsTheVarianceAgainstTheSpread) {
  Pcg32 rng(11, 3);
  std::vector<Vec4f> noise;
  for (int i = 0; i < kSize * kSize; ++i) {
    // Box-Muller: a normal deviate of deviation 0.1 about 1.
    const float u = rng.Uniform(), v = rng.Uniform();
    noise.push_back(Grey(1.0f + 0.1f * std::sqrt(-2.0f * std::log(u)) * std::cos(6.2831853f * v), 0.0f));
  }
  std::vector<EdgeGuide> guides(noise.size(), EdgeGuide{100.0f, 1.0f});
  const auto told = [&](float variance) {
    std::vector<Vec4f> image = noise;
    for (Vec4f& p : image) p.w = variance;
    return image;
  };
  EXPECT_NEAR(Calibration(told(0.01f), guides), 1.0f, 0.1f);
  EXPECT_NEAR(Calibration(told(0.04f), guides), 0.25f, 0.025f);
  EXPECT_NEAR(Calibration(told(0.001f), guides), kCalibrationHighest, 1e-6f) << "loosened beyond the cap";
  EXPECT_NEAR(Calibration(told(0.04f), guides, 0.5f), 0.5f, 1e-6f) << "tightened below the floor";
  EXPECT_NEAR(Calibration(told(0.04f), guides, 1e-3f, 1.0f, 0.9f), 0.9f, 1e-6f) << "fell faster than allowed";
  EXPECT_NEAR(Calibration(told(0.01f), guides, 1e-3f, 0.25f, 0.9f), 1.0f, 0.1f) << "did not rise at once";

  // Escaped pixels, no variance and non-finite colour are not measured: a
  // frame of nothing else leaves the stop as it is.
  std::vector<Vec4f> hostile = told(0.04f);
  for (std::size_t i = 0; i < hostile.size(); i += 3) hostile[i].x = __builtin_nanf("");
  for (std::size_t i = 1; i < hostile.size(); i += 3) hostile[i].w = 0.0f;
  for (std::size_t i = 2; i < hostile.size(); i += 3) guides[i].depth = kEscapedDepth;
  EXPECT_EQ(Calibration(hostile, guides), 1.0f);
}

}  // namespace
}  // namespace cinevol

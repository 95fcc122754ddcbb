// The wRLS update's numerics in isolation: covariance wind-up and its bound,
// a zero weight, exact rescaling, adaptive forgetting, a young model's variance.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "denoise/wrls.h"

namespace cinevol {
namespace {

float Trace(const WrlsModel& m, int c) { return m.p00[c] + m.p11[c]; }

TEST(WrlsNumerics, ConstantPredictorWindsUpWithoutTheBound) {
  WrlsSettings unbounded;
  unbounded.max_trace_p = 3.4e38f;
  WrlsModel m = InitialModel({1, 1, 1}, unbounded.initial_p);
  for (int t = 0; t < 10000; ++t) UpdateChannel(m, 0, 1.0f, 1.0f, 1.0f, unbounded);
  // Only [1, 1] is excited; P grows as lambda^-n along [1, -1]: 0.998^-10000 = 5e8 times its start.
  EXPECT_GT(Trace(m, 0), 1e8f * unbounded.initial_p);
}

TEST(WrlsNumerics, TheTraceBoundHoldsAndTheModelStaysHealthy) {
  const WrlsSettings s;
  WrlsModel m = InitialModel({1, 1, 1}, s.initial_p);
  for (int t = 0; t < 20000; ++t) {
    for (int c = 0; c < 3; ++c) UpdateChannel(m, c, 1.0f, 0.8f, 1.0f, s);
    ASSERT_LE(Trace(m, 0), s.max_trace_p * (1 + 1e-5f));
    ASSERT_TRUE(Healthy(m, s.max_coefficient)) << "step " << t;
  }
  EXPECT_NEAR(m.beta0[0] + m.beta1[0] * 1.0f, 0.8f, 1e-3f);  // predicts what it saw
}

TEST(WrlsNumerics, ZeroWeightOnlyForgets) {
  const WrlsSettings s;
  WrlsModel m = InitialModel({2, 2, 2}, s.initial_p);
  m.beta0 = {0.1f, 0.1f, 0.1f};
  const WrlsModel before = m;
  UpdateChannel(m, 1, 0.7f, 1e30f, 0.0f, s);  // an absurd target with weight 0
  EXPECT_EQ(m.beta0[1], before.beta0[1]);
  EXPECT_EQ(m.beta1[1], before.beta1[1]);
  EXPECT_FLOAT_EQ(m.p00[1], before.p00[1] / s.lambda);
}

TEST(WrlsNumerics, RescalingKeepsPredictions) {
  const WrlsSettings s;
  WrlsModel m = InitialModel({1, 2, 3}, s.initial_p);
  for (int t = 0; t < 50; ++t) {
    for (int c = 0; c < 3; ++c) UpdateChannel(m, c, 1.0f + 0.01f * (t % 7), 1.2f + 0.02f * (t % 5), 1.0f, s);
  }
  const float z = 3.7f;
  auto predict = [&](const WrlsModel& k, int c) { return k.beta0[c] * k.scale + k.beta1[c] * z; };
  WrlsModel r = m;
  Rescale(r, 1e6f);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(predict(r, c), predict(m, c), 1e-4f * std::abs(predict(m, c)));
  EXPECT_TRUE(Healthy(r, s.max_coefficient));
}

// Noise of the size the model expects leaves P alone; a lasting shift of
// three deviations widens it within a few frames and restarts the drift.
TEST(WrlsNumerics, ForgettingAdaptsToADriftNotToNoise) {
  WrlsSettings s;
  s.drift_sigma = 2.0f;
  WrlsModel m = InitialModel({1, 1, 1}, 0.1f);
  m.residual = 0.01f;  // deviation 0.1
  for (int t = 0; t < 200; ++t) {
    AdaptForgetting(m, (t % 2 ? 0.1f : -0.1f), 1.0f, s);
    ASSERT_FLOAT_EQ(m.p00[0], 0.1f) << "frame " << t;
  }
  int frames = 0;
  while (m.p00[0] == 0.1f && frames < 10) {
    AdaptForgetting(m, 0.3f, 1.0f, s);
    ++frames;
  }
  EXPECT_LE(frames, 4);
  EXPECT_FLOAT_EQ(m.p00[0], 1.1f);
  EXPECT_FLOAT_EQ(m.p11[2], 1.1f);
  EXPECT_EQ(m.drift, 0.0f);
}

// A model that has seen no noise yet (residual 0: at 1 spp a dark region's
// first 7x7 neighbourhood can be all black) cannot tell a drift from noise:
// its first bright sample must not throw away the firm prior.
TEST(WrlsNumerics, ForgettingWaitsForANoiseEstimate) {
  WrlsSettings s;
  WrlsModel m = InitialModel({1, 1, 1}, 0.1f);
  m.residual = 0.0f;
  for (int t = 0; t < 10; ++t) AdaptForgetting(m, 5.0f, 1.0f, s);
  EXPECT_FLOAT_EQ(m.p00[0], 0.1f);
  EXPECT_FLOAT_EQ(m.p11[1], 0.1f);
  EXPECT_EQ(m.drift, 0.0f);
}

// A model's first frames are filtered as if its noise were young_variance /
// samples^2 times the residual, when that is more than the fit predicts.
TEST(WrlsNumerics, AYoungModelPredictsAtLeastTheYoungVariance) {
  WrlsModel m = InitialModel({1, 1, 1}, 0.1f);
  m.residual = 0.5f;
  m.samples = 1.0f;
  // Fit's own: beta1^2 / samples + p'Pp = 1 + 0.1 + 0.1 at z = s.
  EXPECT_NEAR(PredictionVariance(m, {1, 1, 1}, 0.0f), 0.5f * 1.2f, 1e-6f);
  EXPECT_NEAR(PredictionVariance(m, {1, 1, 1}, 4.0f), 0.5f * 4.0f, 1e-6f);
  m.samples = 4.0f;  // grown up: the fit's own variance is larger again
  EXPECT_NEAR(PredictionVariance(m, {1, 1, 1}, 4.0f), 0.5f * 0.45f, 1e-6f);
}

// A surface (every pixel of the 5x5 window hit) may have its own floor; a
// pixel by a silhouette or in semi-transparent tissue keeps young_variance.
TEST(WrlsNumerics, TheYoungFloorOnSurfacesIsItsOwn) {
  WrlsSettings s;
  EXPECT_EQ(YoungVariance(s, 1.0f), s.young_variance) << "off by default";
  s.young_variance_surface = 2.0f;
  EXPECT_EQ(YoungVariance(s, 1.0f), 2.0f);
  EXPECT_EQ(YoungVariance(s, 24.0f / 25.0f), s.young_variance);
  EXPECT_EQ(YoungVariance(s, 0.0f), s.young_variance);
}

TEST(WrlsNumerics, OutliersGetNoWeight) {
  EXPECT_NEAR(SampleWeight({1, 1, 1}, {1, 1, 1}, 0.75f, 1e-6f), 1.0f, 1e-6f);
  EXPECT_LT(SampleWeight({1e6f, 1e6f, 1e6f}, {1, 1, 1}, 0.75f, 1e-6f), 1e-30f);
  EXPECT_NEAR(SampleWeight({2, 2, 2}, {1, 1, 1}, 0.75f, 0.0f), std::exp(-1.0f / 0.5625f), 1e-6f);
}

TEST(WrlsNumerics, ASampleBelowTheFeatureWeighsAsOneAsFarAbove) {
  // Weighing dark samples less (the paper's min(|sample|, |z|)) leaned the
  // fit bright by 1.4-1.6% on real volumes.
  EXPECT_NEAR(SampleWeight({0.5f, 0.5f, 0.5f}, {1, 1, 1}, 0.75f, 1e-6f),
              SampleWeight({1.5f, 1.5f, 1.5f}, {1, 1, 1}, 0.75f, 1e-6f), 1e-6f);
  EXPECT_GT(SampleWeight({0, 0, 0}, {1, 1, 1}, 0.75f, 1e-6f), 0.1f) << "a black sample is no outlier of a dim feature";
}

// The stored model's half precision rounds as the GPU's conversion does (to
// nearest, ties to even): every half reads back as itself, a value between
// two neighbours goes to the nearer, a tie to the even one; beyond 65504
// (and past 65520) it overflows to infinity; NaN stays NaN.
TEST(WrlsNumerics, HalfPrecisionRoundsToNearestEven) {
  for (std::uint32_t bits = 0; bits < 0x7c00u; ++bits) {  // the finite positive halves
    const auto h = std::uint16_t(bits), next = std::uint16_t(bits + 1);
    const float a = FromHalf(h), b = FromHalf(next);
    ASSERT_EQ(ToHalf(a), h) << bits;
    ASSERT_EQ(ToHalf(-a), std::uint16_t(h | 0x8000u)) << bits;
    if (next == 0x7c00u) break;  // b is infinity
    const float middle = 0.5f * (a + b);  // exact: a and b are 11-bit numbers
    ASSERT_EQ(ToHalf(middle), (h & 1u) ? next : h) << bits;
    ASSERT_EQ(ToHalf(std::nextafter(middle, 0.0f)), h) << bits;
    ASSERT_EQ(ToHalf(std::nextafter(middle, b)), next) << bits;
  }
  EXPECT_EQ(ToHalf(65519.0f), 0x7bffu);
  EXPECT_EQ(ToHalf(65520.0f), 0x7c00u);
  EXPECT_EQ(ToHalf(3.4e38f), 0x7c00u);
  EXPECT_EQ(ToHalf(1e-9f), 0u);
  EXPECT_TRUE(std::isnan(FromHalf(ToHalf(std::nanf("")))));
  const WrlsModel m = InitialModel({1, 2, 3}, 0.1f);
  const WrlsModel back = Load(Store(m));
  EXPECT_EQ(back.beta1[2], 1.0f);
  EXPECT_EQ(back.p11[1], m.p11[1]);
}

// The normal stop's guide (NormalGuidePass): this frame's normals blended
// into the previous guide where the pixel was reprojected, alone where it
// was not; normals that flip from frame to frame average to a short vector,
// which weakens the stop.
TEST(WrlsNumerics, TheNormalGuideAveragesWhereReprojected) {
  const Vec3f current[2] = {{0, 0, -1}, {0, 0, -1}};
  const Vec3f previous[2] = {{0, 0, 1}, {1, 0, 0}};
  const int previous_pixel[2] = {0, -1};
  Vec3f guide[2];
  const NormalGuidePass pass{current, previous, previous_pixel, guide, 2, 0.25f};
  pass(0, 0);
  pass(1, 0);
  EXPECT_NEAR(guide[0].z, 0.5f, 1e-6f) << "0.75 of the flipped history, 0.25 of this frame";
  EXPECT_LT(Length(guide[0]), 0.6f);
  EXPECT_EQ(guide[1].z, -1.0f) << "no history: this frame's normal";
}

// Three by three pixels through the temporal pass, frame after frame: the
// centre is updated, and each frame's feature and models are the next one's
// history (the camera stands still).
struct ThreeByThree {
  static constexpr int kSide = 3, kPixels = kSide * kSide, kCentre = 4;
  WrlsSettings s;
  std::vector<Vec3f> input = std::vector<Vec3f>(kPixels), feature = std::vector<Vec3f>(kPixels);
  std::vector<Vec4f> history = std::vector<Vec4f>(kPixels), prediction = std::vector<Vec4f>(kPixels);
  std::vector<int> previous_pixel = std::vector<int>(kPixels, -1);
  std::vector<StoredWrlsModel> previous = std::vector<StoredWrlsModel>(kPixels), model = previous;

  // The centre's model after one frame.
  WrlsModel Frame() {
    ReprojectionView rv;
    rv.width = rv.height = kSide;
    WrlsTemporalPass{rv,
                     input.data(),
                     history.data(),
                     previous_pixel.data(),
                     previous.data(),
                     feature.data(),
                     model.data(),
                     prediction.data(),
                     s,
                     0,
                     nullptr,
                     nullptr}(1, 1);
    previous = model;
    for (int i = 0; i < kPixels; ++i) {
      previous_pixel[i] = i;
      history[i] = ToVec4(feature[i], 1.0f);
    }
    return Load(model[kCentre]);
  }
  bool PredictionIsFinite() const { return IsFinite(Xyz(prediction[kCentre])) && std::isfinite(prediction[kCentre].w); }
};

// A bright sample in the dark (no lit neighbour, a black history) is clamped
// out of the feature, which stays black, and weighs 0 in the fit: its error,
// in units of the black model's floor scale, is out of range and must not
// reach the residual (0 times infinity: a NaN that froze the model for good).
TEST(WrlsNumerics, ALoneSampleInTheDarkLeavesAFiniteModel) {
  ThreeByThree square;
  square.Frame();  // all black: a model at the floor scale, no noise seen
  square.input[ThreeByThree::kCentre] = {5.0f, 5.0f, 5.0f};
  const WrlsModel m = square.Frame();
  EXPECT_TRUE(std::isfinite(m.residual) && std::isfinite(m.drift)) << m.residual << " " << m.drift;
  EXPECT_TRUE(Healthy(m, square.s.max_coefficient));
  EXPECT_TRUE(square.PredictionIsFinite());
}

// A black pixel among lit, noisy ones (a silhouette): its noise in its own
// units (scale 1e-20) overflows. It must read as none seen, not stay
// infinite, nor become a NaN on the next frame or when the pixel is lit.
TEST(WrlsNumerics, ABlackPixelAmongLitOnesKeepsAFiniteNoiseEstimate) {
  ThreeByThree square;
  for (int i = 0; i < ThreeByThree::kPixels; ++i) {
    square.input[i] = i % 2 ? Vec3f{2.0f, 2.0f, 2.0f} : Vec3f{0.2f, 0.2f, 0.2f};
  }
  auto frame = [&](float centre) {
    square.input[ThreeByThree::kCentre] = {centre, centre, centre};
    const WrlsModel m = square.Frame();
    EXPECT_TRUE(m.residual >= 0.0f && std::isfinite(m.residual)) << "centre " << centre << ": " << m.residual;
    EXPECT_TRUE(square.PredictionIsFinite());
    return m;
  };
  frame(0.0f);                                             // its first noise estimate
  frame(0.0f);                                             // and its first update
  for (int t = 0; t < 4; ++t) frame(t % 2 ? 0.8f : 1.2f);  // lit, rescaled from the floor
  EXPECT_GT(frame(1.0f).residual, 0.0f);                   // it learns its noise again
}

}  // namespace
}  // namespace cinevol

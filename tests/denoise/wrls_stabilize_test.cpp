// wRLS's output stabilisation (WrlsStabilizePass and its recentering window's
// HistoryOffsetTap summed by RowWindowSums, WindowMean) in isolation: the clip box
// lets a shading change through only partly; recentering the history on its
// mean offset over the window lets it through whole, and noise is still
// averaged.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/rng.h"
#include "device/cpu_backend.h"
#include "denoise/wrls.h"

namespace cinevol {
namespace {

constexpr int kSize = 48;
constexpr float kNoise = 0.05f;  // deviation of both frames' estimates

struct Frames {
  std::vector<Vec4f> current, history;  // estimate with its predicted variance; reprojected history (w = 1)
};

// Grey estimates around `now`, history around `before`, independent noise.
Frames Make(float now, float before) {
  Frames f;
  Pcg32 rng(7, 1);
  auto noisy = [&](float v) { return v + kNoise * 3.4641f * (rng.Uniform() - 0.5f); };  // uniform, std kNoise
  for (int i = 0; i < kSize * kSize; ++i) {
    const float c = noisy(now), h = noisy(before);
    f.current.push_back({c, c, c, kNoise * kNoise});
    f.history.push_back({h, h, h, 1.0f});
  }
  return f;
}

// The stabiliser as the wRLS driver runs it: the recentering's row sums
// first. `only_moved`: the view whose cameras say how far each pixel moved,
// where only the camera did (null: the shading may have changed).
WrlsStabilizePass MakePass(const Frames& f, int recenter, std::vector<Vec4f>& rows, std::vector<Vec3f>& out,
                           std::vector<Vec3f>& kept, const ReprojectionView* only_moved = nullptr) {
  rows.resize(f.current.size());
  out.resize(f.current.size());
  kept.resize(f.current.size());
  CpuBackend::RowWindowSums(kSize, kSize, recenter, kWindowTapStride,
                            HistoryOffsetTap{f.current.data(), f.history.data(), kSize}, rows.data());
  return {f.current.data(), f.history.data(), rows.data(), only_moved ? *only_moved : ReprojectionView{},
          only_moved != nullptr, out.data(), kept.data(), kSize, kSize, 0.5f, 4.0f, recenter};
}

std::vector<Vec3f> Stabilize(const Frames& f, int recenter, const ReprojectionView* only_moved = nullptr) {
  std::vector<Vec4f> rows;
  std::vector<Vec3f> out, kept;
  CpuBackend::ForEachPixel(kSize, kSize, MakePass(f, recenter, rows, out, kept, only_moved));
  EXPECT_EQ(out, kept);
  return out;
}

double Mean(const std::vector<Vec3f>& image) {
  double sum = 0;
  for (const Vec3f& p : image) sum += p.x;
  return sum / double(image.size());
}

double Deviation(const std::vector<Vec3f>& image) {
  const double mean = Mean(image);
  double sum = 0;
  for (const Vec3f& p : image) sum += (p.x - mean) * (p.x - mean);
  return std::sqrt(sum / double(image.size()));
}

TEST(WrlsStabilize, RecenteringLetsAShadingChangeThroughWhole) {
  const Frames brighter = Make(1.0f, 0.7f);  // the light brightened the region by 0.3
  EXPECT_NEAR(Mean(Stabilize(brighter, 3)), 1.0, 0.01);
}

TEST(WrlsStabilize, RecenteringStillAveragesNoise) {
  const Frames still = Make(1.0f, 1.0f);
  std::vector<Vec3f> current;
  for (const Vec4f& c : still.current) current.push_back(Xyz(c));
  const double before = Deviation(current);
  EXPECT_LT(Deviation(Stabilize(still, 3)), 0.8 * before);
  EXPECT_NEAR(Mean(Stabilize(still, 3)), 1.0, 0.01);
}

// Where only the camera moved, a pixel whose content stayed where it was
// keeps its history as it is: the same shift is now the estimate's noise,
// and about half of it (what the clip box leaves) is kept back. Where the
// content moved a pixel or more it is recentred as before.
TEST(WrlsStabilize, WhereOnlyTheCameraMovedAPixelThatStayedIsNotRecentred) {
  const Frames shifted = Make(1.0f, 0.7f);
  const std::vector<Vec4f> hits(kSize * kSize, Vec4f{0, 0, 0, 1});  // everything on the point the camera looks at
  ReprojectionView view;
  view.first_hit = hits.data();
  view.width = view.height = kSize;
  view.camera = view.prev_camera = LookAt({0, -300, 0}, {0, 0, 0}, {0, 0, 1}, 30, kSize, kSize);
  EXPECT_NEAR(Mean(Stabilize(shifted, 3, &view)), 0.86, 0.02) << "still";
  view.prev_camera = LookAt({0, -300, 10}, {0, 0, 10}, {0, 0, 1}, 30, kSize, kSize);  // 10 mm: about 3 pixels
  EXPECT_NEAR(Mean(Stabilize(shifted, 3, &view)), 1.0, 0.01) << "moved";
}

// Row sums added up down the column give the mean over the whole window of
// taps 2 pixels apart, skipping pixels without history and the image's edge.
TEST(WrlsStabilize, TheRowSumsGiveTheWindowMean) {
  Frames f = Make(1.0f, 0.8f);
  for (std::size_t i = 0; i < f.history.size(); i += 5) f.history[i].w = 0.0f;  // disoccluded
  std::vector<Vec4f> rows;
  std::vector<Vec3f> out, kept;
  constexpr int kRecenter = 3;
  const WrlsStabilizePass pass = MakePass(f, kRecenter, rows, out, kept);
  for (const auto& [x, y] : {std::pair{0, 0}, {kSize - 1, 3}, {5, kSize - 2}, {24, 24}}) {
    double sum = 0, n = 0;
    for (int dy = -kRecenter; dy <= kRecenter; ++dy) {
      for (int dx = -kRecenter; dx <= kRecenter; ++dx) {
        const int nx = x + 2 * dx, ny = y + 2 * dy;
        if (nx < 0 || ny < 0 || nx >= kSize || ny >= kSize) continue;
        const int k = ny * kSize + nx;
        if (f.history[k].w == 0.0f) continue;
        sum += f.history[k].x - f.current[k].x;
        n += 1;
      }
    }
    EXPECT_NEAR(WindowMean(pass.offset_rows, kSize, kSize, x, y, kRecenter).x, sum / n, 1e-5) << x << "," << y;
  }
}

// A window wider than a GPU block's shared taps is refused by name, on
// either backend (the check is the same), not read out of bounds.
TEST(RowWindowSums, AWindowReachingTooFarIsRefused) {
  constexpr int kWidth = 2 * kMaxRowReach + 16, kHeight = 2;
  std::vector<Vec4f> rows(kWidth * kHeight);
  const auto tap = [](int, int) { return Vec4f{1, 1, 1, 1}; };
  CpuBackend::RowWindowSums(kWidth, kHeight, kMaxRowReach / 2, 2, tap, rows.data());
  EXPECT_EQ(rows[kWidth + kWidth / 2].w, float(kMaxRowReach + 1));  // every tap within the row
  EXPECT_EQ(rows[kWidth].w, float(kMaxRowReach / 2 + 1));            // the row's first pixel: half the window
  try {
    CpuBackend::RowWindowSums(kWidth, kHeight, kMaxRowReach / 2 + 1, 2, tap, rows.data());
    FAIL() << "a reach of " << kMaxRowReach + 2 << " pixels was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("a reach of at most 32 pixels"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace cinevol

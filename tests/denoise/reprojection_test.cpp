// Reprojection when the camera stays put: a transfer-function or light edit
// changes what a pixel's rays hit, not where the pixel is, so every pixel
// keeps its own history, even one whose first hit flipped between the volume
// and the background.
#include "denoise/reprojection.h"

#include <gtest/gtest.h>

#include <vector>

namespace cinevol {
namespace {

TEST(Reprojection, AnUnmovedCameraKeepsAPixelWhoseFirstHitFlipped) {
  constexpr int kWidth = 8, kHeight = 6;
  const Camera camera = LookAt({0, -300, 0}, {0, 0, 0}, {0, 0, 1}, 30, kWidth, kHeight);
  // Every pixel sees the plane y = 0.
  std::vector<Vec4f> now(kWidth * kHeight);
  for (int py = 0; py < kHeight; ++py) {
    for (int px = 0; px < kWidth; ++px) {
      const Ray r = camera.GenerateRay(px + 0.5f, py + 0.5f, 0.5f, 0.5f);
      now[py * kWidth + px] = ToVec4(r.origin + r.direction * (-r.origin.y / r.direction.y), 1.0f);
    }
  }
  std::vector<Vec4f> before = now;
  const int x = 3, y = 2;
  before[y * kWidth + x] = Vec4f{0, 0, 0, 0};  // escaped last frame, hits now
  ReprojectionView v;
  v.first_hit = now.data();
  v.prev_first_hit = before.data();
  v.camera = v.prev_camera = camera;
  v.width = kWidth;
  v.height = kHeight;
  v.has_history = true;

  v.same_view = true;
  const Reprojection kept = Reproject(v, x, y);
  EXPECT_TRUE(kept.valid);
  EXPECT_EQ(kept.nx, x);
  EXPECT_EQ(kept.ny, y);
  const std::vector<float> history(kWidth * kHeight, 0.25f);
  float sampled = 0;
  ASSERT_TRUE(SampleHistory(v, history.data(), kept, now[y * kWidth + x], sampled));
  EXPECT_EQ(sampled, 0.25f);

  v.same_view = false;  // a moving camera cannot tell this pixel from a disocclusion
  EXPECT_FALSE(Reproject(v, x, y).valid);
}

}  // namespace
}  // namespace cinevol

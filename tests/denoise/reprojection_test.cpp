// Reprojection (denoise/reprojection.h): where the camera moved a pixel's
// history is read where the pixel was, whatever sample found its hit; where
// the camera stood it is read at the hit's own, jittered, position.
#include "denoise/reprojection.h"

#include <gtest/gtest.h>

#include <vector>

namespace cinevol {
namespace {

constexpr int kSize = 32;
constexpr float kDepth = 300.0f;  // mm from the first camera to the plane y = 0 it looks at

Camera CameraAt(float x_mm) { return LookAt({x_mm, -kDepth, 0}, {x_mm, 0, 0}, {0, 0, 1}, 30, kSize, kSize); }

// Where the ray through continuous pixel position (px, py) meets the plane y = y_mm.
Vec4f HitOnPlane(const Camera& camera, float px, float py, float y_mm = 0.0f) {
  const Ray ray = camera.GenerateRay(px, py, 0.5f, 0.5f);
  const float t = (y_mm - ray.origin.y) / ray.direction.y;
  const Vec3f p = ray.origin + ray.direction * t;
  return {p.x, p.y, p.z, 1.0f};
}

// Two frames of the plane: the previous camera's hits through its pixels'
// centres, this camera's through their centres moved by `jitter`.
struct TwoFrames {
  std::vector<Vec4f> hits, prev_hits;
  ReprojectionView view;

  TwoFrames(const Camera& prev, const Camera& now, Vec3f jitter) : hits(kSize * kSize), prev_hits(kSize * kSize) {
    for (int y = 0; y < kSize; ++y) {
      for (int x = 0; x < kSize; ++x) {
        prev_hits[y * kSize + x] = HitOnPlane(prev, x + 0.5f, y + 0.5f);
        hits[y * kSize + x] = HitOnPlane(now, x + 0.5f + jitter.x, y + 0.5f + jitter.y);
      }
    }
    view.first_hit = hits.data();
    view.prev_first_hit = prev_hits.data();
    view.camera = now;
    view.prev_camera = prev;
    view.width = view.height = kSize;
    view.has_history = true;
    view.camera_moved = !SameProjection(now, prev);
  }
};

TEST(Reprojection, AMovedCameraReadsWhereThePixelWasWhateverItsJitter) {
  const Camera prev = CameraAt(0), now = CameraAt(10);  // 10 mm to the right: the plane moves about 2 pixels left
  const float shift = 10.0f / kDepth * (0.5f * kSize / prev.tan_half_fov_y);
  for (const Vec3f jitter : {Vec3f{0, 0, 0}, Vec3f{0.7f, -0.4f, 0}, Vec3f{-1.2f, 0.9f, 0}}) {
    TwoFrames f(prev, now, jitter);
    ASSERT_TRUE(f.view.camera_moved);
    const Reprojection r = Reproject(f.view, 12, 20);
    ASSERT_TRUE(r.valid) << jitter.x;
    EXPECT_NEAR(r.x, 12 + shift, 1e-3) << jitter.x;
    EXPECT_NEAR(r.y, 20, 1e-3) << jitter.x;
    EXPECT_EQ(r.nx, 14);
    EXPECT_EQ(r.ny, 20);
  }
}

// The camera stood and the shading changed: the history is read at the
// hit's own projection, jitter and all (measured to help the denoisers there).
TEST(Reprojection, AStandingCameraReadsAtTheHitsJitteredPosition) {
  const Camera camera = CameraAt(0);
  TwoFrames f(camera, camera, {0.7f, -0.4f, 0});
  ASSERT_FALSE(f.view.camera_moved);
  const Reprojection r = Reproject(f.view, 12, 20);
  ASSERT_TRUE(r.valid);
  EXPECT_NEAR(r.x, 12.7f, 1e-3);
  EXPECT_NEAR(r.y, 19.6f, 1e-3);
  f.view.still = true;  // nothing changed at all: every pixel is its own history
  const Reprojection own = Reproject(f.view, 12, 20);
  EXPECT_EQ(own.x, 12.0f);
  EXPECT_EQ(own.y, 20.0f);
}

// What the previous pixel there saw was an occluder in front of the plane:
// its round trip lands far from the pixel, so the history is refused.
TEST(Reprojection, AMovedCameraStillRejectsADisocclusion) {
  const Camera prev = CameraAt(0), now = CameraAt(20);
  TwoFrames f(prev, now, {0.3f, 0.2f, 0});
  const Reprojection open = Reproject(f.view, 12, 20);
  ASSERT_TRUE(open.valid);
  const int covered = open.ny * kSize + open.nx;
  f.prev_hits[covered] = HitOnPlane(prev, open.nx + 0.5f, open.ny + 0.5f, -200.0f);  // 100 mm from the camera
  EXPECT_FALSE(Reproject(f.view, 12, 20).valid);
}

TEST(Reprojection, OnlyWhatMovesPixelsCountsAsTheCameraMoving) {
  const Camera a = CameraAt(0);
  Camera b = a;
  b.lens_radius = 2.0f;
  b.focal_distance = 100.0f;
  EXPECT_TRUE(SameProjection(a, b));
  b.tan_half_fov_y *= 1.01f;
  EXPECT_FALSE(SameProjection(a, b));
  EXPECT_FALSE(SameProjection(a, CameraAt(0.01f)));
}

}  // namespace
}  // namespace cinevol

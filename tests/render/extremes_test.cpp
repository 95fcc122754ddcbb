// Numerics at the extremes: degenerate volumes, cameras and images, and
// extinction up to 1e6 per mm give finite images in bounded time.
#include <gtest/gtest.h>

#include <chrono>

#include "render/cpu_renderer.h"
#include "render_test_scenes.h"

namespace cinevol {
namespace {

using testing::ConstantMedium;
using testing::UniformCube;
using testing::UniformSky;

// A scene with every feature: BRDF, emission, several lights, many bounces.
LightSetup AllLights() {
  LightSetup s = UniformSky(0.5f);
  Light area;
  area.kind = LightKind::kArea;
  area.position = {0, -200, 200};
  area.edge_u = {50, 0, 0};
  area.edge_v = {0, 35, 35};
  const Vec3f n = Cross(area.edge_u, area.edge_v);
  area.area = Length(n);
  area.normal = n / area.area;
  area.emitted = {5, 5, 5};
  Light point;
  point.kind = LightKind::kPoint;
  point.position = {100, 50, 80};
  point.emitted = {1e4f, 1e4f, 1e4f};
  Light sun;
  sun.kind = LightKind::kDirectional;
  sun.direction = Normalize(Vec3f{-1, 1, -1});
  sun.emitted = {2, 2, 2};
  s.lights = {area, point, sun};
  return s;
}

TransferFunction EmissiveHybrid(float density) {
  TransferFunction tf = ConstantMedium(density, 0.7f, 1.0f);
  tf.points[1].emission = {0.1f, 0.05f, 0.0f};
  tf.points[0].value = 0.0f;   // a ramp, so gradients exist
  tf.points[0].opacity = 0.0f;
  tf.points[1].value = 1000.0f;
  return tf;
}

struct Outcome {
  bool finite = true;
  double seconds = 0;
};

Outcome RenderOnce(std::shared_ptr<const Volume> volume, const TransferFunction& tf, const Camera& camera,
                   int spp = 2, int bounces = 8) {
  CpuRenderer r;
  r.SetVolume(volume);
  r.SetTransferFunction(tf);
  r.SetLights(AllLights());
  FrameRequest req;
  req.camera = camera;
  req.spp = spp;
  req.max_bounces = bounces;
  const auto start = std::chrono::steady_clock::now();
  r.Render(req);
  Outcome o;
  o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  for (const Vec3f& p : r.Radiance().pixels) o.finite &= IsFinite(p) && MinComponent(p) >= 0.0f;
  for (const Vec4f& h : r.FirstHits()) o.finite &= std::isfinite(h.x) && std::isfinite(h.y) && std::isfinite(h.z);
  return o;
}

Camera Oblique(int w = 24, int h = 18) { return LookAt({70, -90, 50}, {0, 0, 0}, {0, 0, 1}, 40, w, h); }

std::shared_ptr<const Volume> Sphere(int size, float spacing) {
  v1::Phantom p;
  p.set_kind(v1::Phantom::SPHERE);
  p.set_size(size);
  p.set_spacing(spacing);
  return std::make_shared<const Volume>(MakePhantom(p));
}

TEST(Extremes, EmptyVolume) {
  EXPECT_TRUE(RenderOnce(UniformCube(8, 2.0f, 0.0f), EmissiveHybrid(1.0f), Oblique()).finite);
}

TEST(Extremes, OneVoxelVolume) {
  EXPECT_TRUE(RenderOnce(UniformCube(1, 10.0f, 1000.0f), EmissiveHybrid(1.0f), Oblique()).finite);
}

TEST(Extremes, CameraInsideTheVolume) {
  const Camera inside = LookAt({1, 2, 3}, {10, 0, 0}, {0, 0, 1}, 60, 16, 16);
  EXPECT_TRUE(RenderOnce(Sphere(32, 2.0f), EmissiveHybrid(0.05f), inside).finite);
}

TEST(Extremes, RaysGrazingTheBox) {
  // The eye sits in the plane of a face, looking along it.
  const Camera grazing = LookAt({-16, -200, 16}, {-16, 0, 16}, {0, 0, 1}, 2, 16, 16);
  EXPECT_TRUE(RenderOnce(UniformCube(16, 2.0f, 1000.0f), EmissiveHybrid(1.0f), grazing).finite);
}

TEST(Extremes, TinyAndHugeSpacing) {
  EXPECT_TRUE(RenderOnce(Sphere(16, 1e-3f), EmissiveHybrid(1.0f),
                         LookAt({0.02f, -0.03f, 0.01f}, {0, 0, 0}, {0, 0, 1}, 40, 16, 16)).finite);
  EXPECT_TRUE(RenderOnce(Sphere(16, 100.0f), EmissiveHybrid(1e-3f),
                         LookAt({2000, -3000, 1000}, {0, 0, 0}, {0, 0, 1}, 40, 16, 16)).finite);
}

TEST(Extremes, ExtinctionOfAMillionPerMillimetre) {
  for (float density : {1e3f, 1e6f}) {
    const Outcome o = RenderOnce(Sphere(32, 1.0f), EmissiveHybrid(density), Oblique(), 2, 64);
    EXPECT_TRUE(o.finite) << density;
    EXPECT_LT(o.seconds, 30.0) << "bounded loops: " << density;
  }
}

TEST(Extremes, OnePixelImage) {
  EXPECT_TRUE(RenderOnce(Sphere(16, 2.0f), EmissiveHybrid(0.1f), Oblique(1, 1)).finite);
}

TEST(Extremes, LargestImage) {
  // 8192^2: the frame buffers hold radiance, first hit and the accumulation.
  CpuRenderer r;
  r.SetVolume(UniformCube(2, 1.0f, 0.0f));
  r.SetTransferFunction(ConstantMedium(0.0f, 0.5f));
  r.SetLights(UniformSky(1.0f));
  FrameRequest req;
  req.camera = LookAt({0, -100, 0}, {0, 0, 0}, {0, 0, 1}, 10, 8192, 8192);
  req.max_bounces = 0;
  r.Render(req);
  const ImageRgbF image = r.Radiance();
  ASSERT_EQ(image.pixels.size(), std::size_t(8192) * 8192);
  EXPECT_EQ(image.pixels.front().x, 1.0f);
  EXPECT_EQ(image.pixels.back().z, 1.0f);
}

}  // namespace
}  // namespace cinevol

// The CUDA backend against the CPU backend: converged images agree within
// noise on a scene using every feature. Skips where no GPU is usable.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "io/phantom.h"
#include "render/renderer.h"
#include "render_test_scenes.h"
#include "scene/scene_builder.h"
#include "support/gpu.h"

namespace cinevol {
namespace {

using testing::ConstantMedium;
using testing::UniformCube;
using testing::UniformSky;

// Every feature at once: hybrid BRDF, emission, an environment map, area,
// point and directional lights, multiple scattering.
struct FullScene {
  std::shared_ptr<const Volume> volume;
  TransferFunction tf;
  LightSetup lights;
  Camera camera;
  ClipRegion clip;  // none unless a test sets one
  Reconstruction reconstruction = Reconstruction::kTrilinear;
  std::shared_ptr<const LabelVolume> labels;  // none unless a test sets one
  LabelSetup label_setup;
  std::shared_ptr<const Volume> fused;  // a second volume (Scene.fusion); none unless a test sets one
  FusionSetup fusion;

  FullScene() {
    v1::Phantom p;
    p.set_kind(v1::Phantom::HEAD);
    p.set_size(64);
    p.set_spacing(4.0f);
    volume = std::make_shared<const Volume>(MakePhantom(p));
    tf.points = {{-200, 0, {0.9f, 0.6f, 0.5f}, {}, 0.5f, {}},
                 {0, 0.1f, {0.9f, 0.6f, 0.5f}, {0.1f, 0.1f, 0.1f}, 0.5f, {0.02f, 0.0f, 0.0f}},
                 {300, 0.8f, {0.9f, 0.9f, 0.8f}, {0.3f, 0.3f, 0.3f}, 0.3f, {}},
                 {1500, 1, {0.9f, 0.9f, 0.8f}, {0.3f, 0.3f, 0.3f}, 0.3f, {}}};
    tf.density_scale = 0.3f;
    tf.gradient_factor = 1.5f;
    tf.phase_g = 0.3f;
    lights.environment.kind = Environment::Kind::kMap;
    lights.environment.map = {8, 4, std::vector<Vec3f>(32, Vec3f{0.3f, 0.35f, 0.4f})};
    lights.environment.map.pixels[9] = {30, 25, 20};
    Light area;
    area.kind = LightKind::kArea;
    area.position = {-200, -300, 250};
    area.edge_u = {0, 80, 80};
    area.edge_v = {100, -60, 0};
    const Vec3f n = Cross(area.edge_u, area.edge_v);
    area.area = Length(n);
    area.normal = n / area.area;
    area.emitted = {6, 6, 6};
    area.two_sided = 1;
    Light point;
    point.kind = LightKind::kPoint;
    point.position = {250, -150, 0};
    point.emitted = {3e4f, 3e4f, 3e4f};
    Light sun;
    sun.kind = LightKind::kDirectional;
    sun.direction = Normalize(Vec3f{0.2f, 1, -0.5f});
    sun.emitted = {1, 1, 1};
    lights.lights = {area, point, sun};
    camera = LookAt({-250, -500, 150}, {0, 0, 0}, {0, 0, 1}, 30, 32, 24);
  }
};

struct PixelEstimates {
  std::vector<double> mean, stderr_of_mean;
};

PixelEstimates Estimate(Renderer& r, const FullScene& s, int frames, int spp) {
  r.SetVolume(s.volume);
  r.SetTransferFunction(s.tf);
  r.SetLights(s.lights);
  r.SetClipRegion(s.clip);
  r.SetReconstruction(s.reconstruction);
  r.SetLabels(s.labels, s.label_setup);
  r.SetFusion(s.fused, s.fusion);
  const std::size_t n = std::size_t(s.camera.width) * s.camera.height;
  std::vector<double> sum(n), sum2(n);
  for (int f = 0; f < frames; ++f) {
    FrameRequest req;
    req.camera = s.camera;
    req.spp = spp;
    req.max_bounces = 6;
    req.frame = f;
    r.Render(req);
    const ImageRgbF image = r.Radiance();
    for (std::size_t i = 0; i < n; ++i) {
      const double v = Luminance(image.pixels[i]);
      sum[i] += v;
      sum2[i] += v * v;
    }
  }
  PixelEstimates e{std::vector<double>(n), std::vector<double>(n)};
  for (std::size_t i = 0; i < n; ++i) {
    e.mean[i] = sum[i] / frames;
    e.stderr_of_mean[i] = std::sqrt(std::max(0.0, sum2[i] / frames - e.mean[i] * e.mean[i]) / (frames - 1));
  }
  return e;
}

// Per pixel, the two backends' estimates differ by no more than their noise.
void ExpectAgree(const FullScene& scene) {
  auto cpu = CreateRenderer(Backend::kCpu), cuda = CreateRenderer(Backend::kCuda);
  const PixelEstimates a = Estimate(*cpu, scene, 64, 4), b = Estimate(*cuda, scene, 64, 4);
  double mean_a = 0, mean_b = 0, var = 0, z2 = 0;
  int outliers = 0, counted = 0;
  for (std::size_t i = 0; i < a.mean.size(); ++i) {
    mean_a += a.mean[i] / a.mean.size();
    mean_b += b.mean[i] / a.mean.size();
    const double s2 = a.stderr_of_mean[i] * a.stderr_of_mean[i] + b.stderr_of_mean[i] * b.stderr_of_mean[i];
    var += s2 / (a.mean.size() * a.mean.size());
    if (s2 <= 0) {
      EXPECT_NEAR(a.mean[i], b.mean[i], 1e-4 * std::max(1.0, a.mean[i])) << "noise-free pixel " << i;
      continue;
    }
    const double z = (a.mean[i] - b.mean[i]) / std::sqrt(s2);
    z2 += z * z;
    outliers += std::abs(z) > 4.5;
    ++counted;
  }
  EXPECT_NEAR(mean_a, mean_b, 4 * std::sqrt(var)) << "image means";
  EXPECT_LT(std::sqrt(z2 / counted), 1.5) << "rms z-score over " << counted << " pixels";
  EXPECT_LE(outliers, counted / 100 + 1);
}

TEST(CudaRenderer, ConvergedImagesAgreeWithCpu) {
  CINEVOL_REQUIRE_CUDA();
  ExpectAgree(FullScene{});
}

// An oblique, capped clip plane and a crop box (issue 22).
TEST(CudaRenderer, ClippedImagesAgreeWithCpu) {
  CINEVOL_REQUIRE_CUDA();
  FullScene scene;
  scene.clip.half_spaces[scene.clip.count++] = ToVec4(Normalize(Vec3f{1, 1, 0.5f}), 10.0f);
  scene.clip.capped = 1u;        // the oblique cut shows the tissue it crosses
  for (int a = 0; a < 3; ++a) {  // a 160 mm cube around the centre
    Vec3f n{};
    n[a] = 1;
    scene.clip.half_spaces[scene.clip.count++] = ToVec4(n, 80.0f);
    scene.clip.half_spaces[scene.clip.count++] = ToVec4(-n, 80.0f);
  }
  ExpectAgree(scene);
}

// Tricubic reconstruction (8 texture fetches on the GPU, 64 voxel reads on
// the CPU) and a segmentation: one label hidden, one recoloured and dimmed,
// one with a transfer function of its own (issue 22).
TEST(CudaRenderer, TricubicAndLabelledImagesAgreeWithCpu) {
  CINEVOL_REQUIRE_CUDA();
  FullScene scene;
  scene.reconstruction = Reconstruction::kTricubic;
  auto labels = std::make_shared<LabelVolume>();
  labels->dims = scene.volume->dims();
  labels->labels.resize(scene.volume->voxel_count());
  for (std::size_t i = 0; i < labels->labels.size(); ++i) {
    const int x = int(i % 64), z = int(i / (64 * 64));
    labels->labels[i] = std::uint16_t(x < 24 ? 1 : (z < 32 ? 2 : 3));
    ++labels->voxels[labels->labels[i]];
  }
  scene.labels = labels;
  scene.label_setup.styles[1].visible = false;
  scene.label_setup.styles[2].has_color = true;
  scene.label_setup.styles[2].color = {0.2f, 0.4f, 0.9f};
  scene.label_setup.styles[2].opacity_scale = 0.5f;
  scene.label_setup.styles[3].transfer = 0;
  TransferFunction own = scene.tf;
  for (auto& p : own.points) p.diffuse = {0.9f, 0.2f, 0.2f};
  scene.label_setup.transfer_functions.push_back(own);
  ExpectAgree(scene);
}

// A second volume on a grid of its own (coarser, offset by half its voxel)
// that emits and scatters where the head is: the kFusion variants agree.
TEST(CudaRenderer, FusedImagesAgreeWithCpu) {
  CINEVOL_REQUIRE_CUDA();
  FullScene scene;
  v1::Phantom p;
  p.set_kind(v1::Phantom::SPHERE);
  p.set_size(40);
  p.set_spacing(5.0f);
  p.set_radius(60.0f);
  auto sphere = MakePhantom(p);
  VolumeMetadata meta = sphere.metadata();
  meta.origin_mm[0] += 2.5;
  std::vector<float> values(sphere.voxel_count());
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = sphere.ValueAtIndex(i);
  scene.fused = std::make_shared<const Volume>(sphere.dims(), sphere.spacing_mm(), std::move(values), meta);
  scene.fusion.transfer_function.points = {{0, 0, {1, 0.4f, 0.1f}, {}, 0.5f, {}},
                                           {1000, 0.05f, {1, 0.4f, 0.1f}, {}, 0.5f, {2, 0.8f, 0.2f}}};
  scene.fusion.transfer_function.density_scale = 0.3f;
  scene.fusion.to_volume = ResolveFusion(v1::Fusion{}, *scene.volume, *scene.fused).to_volume;
  ExpectAgree(scene);
}

TEST(CudaRenderer, SameSeedSameImage) {
  CINEVOL_REQUIRE_CUDA();
  const FullScene scene;
  auto render = [&] {
    auto r = CreateRenderer(Backend::kCuda);
    Estimate(*r, scene, 1, 2);
    return r->Radiance();
  };
  const ImageRgbF a = render(), b = render();
  EXPECT_EQ(std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * sizeof(Vec3f)), 0);
}

// On the GPU two lanes share a pixel's samples (cuda_renderer.cu). At an odd
// spp and a size that leaves tiles part empty, each pixel must still add
// exactly its own samples: the ones the CPU traces from the same seeds. A
// constant medium keeps both backends on the same paths, so nearly every
// pixel matches; a sample dropped, doubled or taken from the wrong lane
// would part most of them.
TEST(CudaRenderer, PixelsSharedByTwoLanesAddTheCpusSamples) {
  CINEVOL_REQUIRE_CUDA();
  auto cpu = CreateRenderer(Backend::kCpu), cuda = CreateRenderer(Backend::kCuda);
  FrameRequest req;
  req.camera = testing::AxisCamera(13, 11);
  req.spp = 3;
  req.max_bounces = 4;
  for (Renderer* r : {cpu.get(), cuda.get()}) {
    r->SetVolume(UniformCube(16, 2.0f));
    r->SetTransferFunction(ConstantMedium(1.0f / 32.0f, 0.8f));
    r->SetLights(UniformSky(1.0f));
    r->Render(req);
  }
  const ImageRgbF a = cpu->Radiance(), b = cuda->Radiance();
  ASSERT_EQ(a.pixels.size(), b.pixels.size());
  int same = 0;
  for (std::size_t i = 0; i < a.pixels.size(); ++i) {
    const float la = Luminance(a.pixels[i]), lb = Luminance(b.pixels[i]);
    same += std::abs(la - lb) <= 1e-3f * std::max(1.0f, la);
  }
  EXPECT_GE(same, int(0.95 * a.pixels.size())) << "pixels whose samples match the CPU's, of " << a.pixels.size();
}

TEST(CudaRenderer, AbsorbingCubeMatchesBeerLambert) {
  CINEVOL_REQUIRE_CUDA();
  auto r = CreateRenderer(Backend::kCuda);
  r->SetVolume(UniformCube(16, 2.0f));
  r->SetTransferFunction(ConstantMedium(1.0f / 32.0f, 0.0f));
  r->SetLights(UniformSky(1.0f));
  FrameRequest req;
  req.camera = testing::AxisCamera(64, 64);
  req.spp = 256;
  r->Render(req);
  double mean = 0;
  for (const Vec3f& p : r->Radiance().pixels) mean += p.y / (64.0 * 64);
  const double expected = std::exp(-1.0), sigma = std::sqrt(expected * (1 - expected) / (64.0 * 64 * 256));
  EXPECT_NEAR(mean, expected, 3 * sigma);
}

TEST(CudaRenderer, FirstHitsAndAccumulationMatchTheCpuLayout) {
  CINEVOL_REQUIRE_CUDA();
  auto r = CreateRenderer(Backend::kCuda);
  r->SetVolume(UniformCube(16, 2.0f));
  r->SetTransferFunction(ConstantMedium(10.0f, 0.5f));  // opaque: first hit at the front face
  r->SetLights(UniformSky(1.0f));
  FrameRequest req;
  req.camera = testing::AxisCamera(8, 8);
  for (int f = 0; f < 3; ++f) {
    req.frame = f;
    r->Render(req);
  }
  EXPECT_EQ(r->accumulated_frames(), 3);
  for (const Vec4f& h : r->FirstHits()) {
    EXPECT_EQ(h.w, 1.0f);
    // The cube's face at y = -16 mm, within the medium's free paths (mean 0.1 mm:
    // one of 64 pixels went 0.6 mm deep in one run; beyond 2 mm is e^-20).
    EXPECT_NEAR(h.y, -16.0f, 2.0f);
  }
  EXPECT_EQ(r->AccumulatedMean().pixels.size(), 64u);
}

// FrameTargets::surface_normal: the GPU's, from its own first hits, as the
// CPU's on an opaque ball (most pixels' samples are the CPU's, above).
TEST(CudaRenderer, SurfaceNormalsMatchTheCpus) {
  CINEVOL_REQUIRE_CUDA();
  std::vector<Vec3f> normals[2];
  for (const Backend backend : {Backend::kCpu, Backend::kCuda}) {
    auto r = CreateRenderer(backend);
    r->SetVolume(testing::Ball());
    r->SetTransferFunction(testing::BallSurface());
    r->SetLights(UniformSky(1.0f));
    FrameRequest req;
    req.camera = LookAt({0, -200, 0}, {0, 0, 0}, {0, 0, 1}, 30.0f, 48, 48);
    req.spp = 2;
    req.surface_normals = true;
    r->Render(req);
    normals[backend == Backend::kCuda] = r->SurfaceNormals();
  }
  ASSERT_EQ(normals[1].size(), normals[0].size());
  int same = 0, surfaces = 0;
  for (std::size_t i = 0; i < normals[0].size(); ++i) {
    same += Length(normals[0][i] - normals[1][i]) <= 1e-3f;
    surfaces += Length(normals[1][i]) > 0.5f;
  }
  EXPECT_GE(same, int(0.9 * normals[0].size())) << "pixels whose normals match the CPU's";
  EXPECT_GT(surfaces, 150) << "the ball's surface seen by the GPU";
}

// A reset clears nothing: the frame after it writes the sums instead of adding
// to them. Two frames, a reset, two more: the accumulation holds the last two only.
void ExpectAnAccumulationHoldsTheFramesSinceItsReset(Backend backend) {
  auto r = CreateRenderer(backend);
  r->SetVolume(UniformCube(16, 2.0f));
  r->SetTransferFunction(ConstantMedium(0.2f, 0.7f));
  r->SetLights(UniformSky(1.0f));
  FrameRequest req;
  req.camera = testing::AxisCamera(8, 8);
  req.spp = 2;
  auto render = [&](int frame) {
    req.frame = frame;
    r->Render(req);
    return r->Radiance().pixels;
  };
  render(0);
  render(1);
  r->ResetAccumulation();
  for (const Vec3f& p : r->AccumulatedMean().pixels) EXPECT_EQ(p, (Vec3f{}));
  const std::vector<Vec3f> a = render(2), b = render(3);
  EXPECT_EQ(r->accumulated_frames(), 2);
  const std::vector<Vec3f> mean = r->AccumulatedMean().pixels;
  ASSERT_EQ(mean.size(), a.size());
  for (std::size_t i = 0; i < mean.size(); ++i) {
    const Vec3f expected = (a[i] + b[i]) * 0.5f;
    EXPECT_NEAR(mean[i].x, expected.x, 1e-5f * (1 + expected.x)) << "pixel " << i;
    EXPECT_NEAR(mean[i].y, expected.y, 1e-5f * (1 + expected.y)) << "pixel " << i;
  }
}

TEST(CpuRenderer, AnAccumulationHoldsTheFramesSinceItsReset) {
  ExpectAnAccumulationHoldsTheFramesSinceItsReset(Backend::kCpu);
}

TEST(CudaRenderer, AnAccumulationHoldsTheFramesSinceItsReset) {
  CINEVOL_REQUIRE_CUDA();
  ExpectAnAccumulationHoldsTheFramesSinceItsReset(Backend::kCuda);
}

}  // namespace
}  // namespace cinevol

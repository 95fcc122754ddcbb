// The path tracer against analytic answers: Beer-Lambert transmittance,
// the white furnace, determinism, and specialised against general variants.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "io/label_volume.h"
#include "io/phantom.h"
#include "render/cpu_renderer.h"
#include "render_test_scenes.h"

namespace cinevol {
namespace {

using testing::AxisCamera;
using testing::ConstantMedium;
using testing::UniformCube;
using testing::UniformSky;

FrameRequest Request(const Camera& camera, int spp, int frame, int max_bounces, unsigned features = kAutoFeatures) {
  FrameRequest req;
  req.camera = camera;
  req.spp = spp;
  req.max_bounces = max_bounces;
  req.frame = frame;
  req.seed = 7;
  req.features = features;
  return req;
}

struct Stats {
  double mean = 0, stderr_of_mean = 0, max = 0, min = 0;
  bool finite = true;
};

// Renders `frames` frames of `spp` and returns per-channel-green statistics
// of the per-frame pixel means (frames are independent estimates).
Stats RenderStats(CpuRenderer& r, const Camera& camera, int spp, int frames, int max_bounces,
                  unsigned features = kAutoFeatures) {
  std::vector<double> frame_means;
  Stats s;
  s.min = 1e30;
  for (int f = 0; f < frames; ++f) {
    r.Render(Request(camera, spp, f, max_bounces, features));
    double sum = 0;
    for (const Vec3f& p : r.Radiance().pixels) {
      s.finite &= IsFinite(p);
      sum += p.y;
      s.max = std::max(s.max, double(p.y));
      s.min = std::min(s.min, double(p.y));
    }
    frame_means.push_back(sum / r.Radiance().pixels.size());
  }
  for (double m : frame_means) s.mean += m / frames;
  double var = 0;
  for (double m : frame_means) var += (m - s.mean) * (m - s.mean) / (frames - 1);
  s.stderr_of_mean = std::sqrt(var / frames);
  return s;
}

TEST(Integrator, AbsorbingCubeMatchesBeerLambert) {
  for (float tau : {0.1f, 1.0f, 3.0f}) {
    CpuRenderer r;
    auto cube = UniformCube(16, 2.0f);  // 32 mm across
    const float chord = 32.0f;
    r.SetVolume(cube);
    r.SetTransferFunction(ConstantMedium(tau / chord, 0.0f));
    r.SetLights(UniformSky(1.0f));
    const Stats s = RenderStats(r, AxisCamera(), 64, 8, 4);
    const double expected = std::exp(-double(tau));
    // Binomial per sample: the mean of n escapes has variance T(1-T)/n.
    const double n = 16.0 * 16 * 64 * 8;
    const double sigma = std::sqrt(expected * (1 - expected) / n);
    EXPECT_NEAR(s.mean, expected, 3 * sigma) << "tau " << tau;
    EXPECT_TRUE(s.finite);
  }
}

// A plane through the cube's middle, across the rays, keeps half of each
// chord: the transmittance is that of the half (issue 22). Either side.
TEST(Integrator, ACubeCutInHalfTransmitsTheRemainingChord) {
  const float tau = 2.0f, chord = 32.0f;
  const double expected = std::exp(-double(tau) / 2);
  const double sigma = std::sqrt(expected * (1 - expected) / (16.0 * 16 * 64 * 8));
  for (const float side : {1.0f, -1.0f}) {
    CpuRenderer r;
    r.SetVolume(UniformCube(16, 2.0f));
    r.SetTransferFunction(ConstantMedium(tau / chord, 0.0f));
    r.SetLights(UniformSky(1.0f));
    ClipRegion clip;
    clip.half_spaces[clip.count++] = {0.0f, side, 0.0f, 0.0f};  // keeps y >= 0 (or y <= 0)
    r.SetClipRegion(clip);
    const Stats s = RenderStats(r, AxisCamera(), 64, 8, 4);
    EXPECT_NEAR(s.mean, expected, 3 * sigma) << "side " << side;
  }
}

// A crop that keeps nothing of the volume renders the background alone.
TEST(Integrator, ACropThatRemovesEverythingShowsTheBackground) {
  CpuRenderer r;
  r.SetVolume(UniformCube(16, 2.0f));
  r.SetTransferFunction(ConstantMedium(1.0f, 0.5f));
  r.SetLights(UniformSky(1.0f));
  ClipRegion clip;
  clip.half_spaces[clip.count++] = {1.0f, 0.0f, 0.0f, -100.0f};  // keeps x >= 100 mm: outside the 32 mm cube
  r.SetClipRegion(clip);
  const Stats s = RenderStats(r, AxisCamera(), 4, 2, 4);
  EXPECT_EQ(s.min, 1.0);
  EXPECT_EQ(s.max, 1.0);
}

// A capped cut through an opaque cube: camera rays meet the cut face as a
// diffuse surface of the tissue's colour, facing the camera under a uniform
// sky of radiance 1, so the face shows its albedo (one bounce: the sky
// directly). Uncapped, the same rays go into the medium and see its inside.
TEST(Integrator, ACappedCutShowsTheTissueColour) {
  const float albedo = 0.6f;
  double capped_mean = 0, uncapped_mean = 0;
  for (const bool cap : {true, false}) {
    CpuRenderer r;
    r.SetVolume(UniformCube(16, 2.0f));
    TransferFunction tf = ConstantMedium(10.0f, albedo, 1.0f);
    for (auto& p : tf.points) p.specular = {0, 0, 0};
    r.SetTransferFunction(tf);
    r.SetLights(UniformSky(1.0f));
    ClipRegion clip;
    clip.half_spaces[clip.count++] = {0.0f, 1.0f, 0.0f, 0.0f};  // keeps y >= 0; the camera looks along +y
    clip.capped = cap ? 1u : 0u;
    r.SetClipRegion(clip);
    const Stats s = RenderStats(r, AxisCamera(), 64, 4, 1);
    (cap ? capped_mean : uncapped_mean) = s.mean;
    EXPECT_TRUE(s.finite);
  }
  EXPECT_NEAR(capped_mean, albedo, 0.02) << "the cap shows the tissue's diffuse colour";
  EXPECT_GT(std::abs(uncapped_mean - capped_mean), 0.05) << "without the cap the rays enter the medium";
}

// Two balls, A and B, in 2 mm voxels; A lies inside a brick-aligned block
// labelled 1, two voxels clear of its faces, so hiding label 1 leaves every
// brick's majorant as it would be without A (issue 22).
std::shared_ptr<const Volume> TwoBalls(bool with_a) {
  const int n = 32;
  std::vector<float> v(std::size_t(n) * n * n, 0.0f);
  auto ball = [&](Vec3f c, float r) {
    for (int z = 0; z < n; ++z)
      for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x)
          if (Length(Vec3f{float(x), float(y), float(z)} - c) <= r) v[(std::size_t(z) * n + y) * n + x] = 1000.0f;
  };
  if (with_a) ball({11.5f, 15.5f, 15.5f}, 2.5f);
  ball({25.5f, 15.5f, 15.5f}, 3.0f);
  VolumeMetadata meta;
  meta.source = with_a ? "two balls" : "ball B";
  return std::make_shared<const Volume>(Vec3i{n, n, n}, Vec3f{2, 2, 2}, std::move(v), meta);
}

std::shared_ptr<const LabelVolume> BallALabelled() {
  auto labels = std::make_shared<LabelVolume>();
  labels->dims = {32, 32, 32};
  labels->labels.assign(32 * 32 * 32, 0);
  for (int z = 4; z < 28; ++z)
    for (int y = 4; y < 28; ++y)
      for (int x = 4; x < 20; ++x) labels->labels[(std::size_t(z) * 32 + y) * 32 + x] = 1;
  for (std::uint16_t l : labels->labels) ++labels->voxels[l];
  return labels;
}

ImageRgbF RenderBalls(const std::shared_ptr<const Volume>& volume, const std::shared_ptr<const LabelVolume>& labels,
                      const LabelSetup& setup) {
  CpuRenderer r;
  r.SetVolume(volume);
  TransferFunction tf;
  tf.points = {{400, 0, {0.8f, 0.8f, 0.8f}, {}, 0.5f, {}}, {600, 1, {0.8f, 0.8f, 0.8f}, {}, 0.5f, {}}};
  tf.density_scale = 5;
  r.SetTransferFunction(tf);
  r.SetLights(UniformSky(1.0f));
  r.SetLabels(labels, setup);
  // Every feature, with labels or without: the same integrator draws the same
  // random numbers (a labelled scene takes every feature; render/render_scene.h).
  r.Render(Request(LookAt({0, -200, 0}, {0, 0, 0}, {0, 0, 1}, 30.0f, 24, 24), 8, 0, 2, kAllFeatures));
  return r.Radiance();
}

TEST(Integrator, ABallHiddenByItsLabelLeavesTheImageWithoutIt) {
  LabelSetup hide_a;
  hide_a.styles[1].visible = false;
  const ImageRgbF hidden = RenderBalls(TwoBalls(true), BallALabelled(), hide_a);
  const ImageRgbF without = RenderBalls(TwoBalls(false), nullptr, {});
  const ImageRgbF shown = RenderBalls(TwoBalls(true), BallALabelled(), {});
  int differ = 0;
  for (std::size_t i = 0; i < hidden.pixels.size(); ++i) {
    ASSERT_EQ(hidden.pixels[i], without.pixels[i]) << "pixel " << i;
    differ += !(shown.pixels[i] == without.pixels[i]);
  }
  EXPECT_GT(differ, 10) << "ball A shows while its label is visible";
}

// A label's colour replaces the diffuse colour of its voxels only, and a
// label with a transfer function of its own shows through it: here one that
// sees nothing, so ball A goes as if hidden.
TEST(Integrator, ALabelsColourAndOwnTransferFunctionApplyToItsVoxelsOnly) {
  LabelSetup red;
  red.styles[1].has_color = true;
  red.styles[1].color = {1, 0, 0};
  const ImageRgbF coloured = RenderBalls(TwoBalls(true), BallALabelled(), red);
  const ImageRgbF plain = RenderBalls(TwoBalls(true), BallALabelled(), {});
  double red_gain = 0, green_gain = 0;
  for (std::size_t i = 0; i < plain.pixels.size(); ++i) {
    red_gain += coloured.pixels[i].x - plain.pixels[i].x;
    green_gain += coloured.pixels[i].y - plain.pixels[i].y;
  }
  EXPECT_GT(red_gain, 0.2) << "green " << green_gain;
  EXPECT_LT(green_gain, -0.6) << "red " << red_gain;

  LabelSetup clear;
  clear.styles[1].transfer = 0;
  TransferFunction nothing;
  nothing.points = {{0, 0, {1, 1, 1}, {}, 0.5f, {}}, {1000, 0, {1, 1, 1}, {}, 0.5f, {}}};
  clear.transfer_functions.push_back(nothing);
  const ImageRgbF own = RenderBalls(TwoBalls(true), BallALabelled(), clear);
  const ImageRgbF without = RenderBalls(TwoBalls(false), nullptr, {});
  for (std::size_t i = 0; i < own.pixels.size(); ++i) ASSERT_EQ(own.pixels[i], without.pixels[i]) << "pixel " << i;
}

// Issue 32: a segmentation that stops short of a structure's partial-volume
// rim leaves the rim at label 0. Ball A here has a rim of half its value one
// voxel deep, and only its core is labelled: hidden without its shell, the
// rim still shows; with it (FitLabels adds shells), nothing of ball A does.
TEST(Integrator, AHiddenLabelTakesItsUnlabelledShellAlong) {
  const int n = 32;
  std::vector<float> values(std::size_t(n) * n * n, 0.0f);
  auto labels = std::make_shared<LabelVolume>();
  labels->dims = {n, n, n};
  labels->labels.assign(values.size(), 0);
  const Vec3f a{11.5f, 15.5f, 15.5f}, b{25.5f, 15.5f, 15.5f};
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        const std::size_t i = (std::size_t(z) * n + y) * n + x;
        const Vec3f p{float(x), float(y), float(z)};
        const float ra = Length(p - a);
        values[i] = ra <= 3.0f || Length(p - b) <= 3.0f ? 1000.0f : (ra <= 4.0f ? 500.0f : 0.0f);
        if (ra <= 3.0f) labels->labels[i] = 1;
      }
  for (std::uint16_t l : labels->labels) ++labels->voxels[l];
  const auto volume =
      std::make_shared<const Volume>(Vec3i{n, n, n}, Vec3f{2, 2, 2}, std::move(values), VolumeMetadata{});
  auto with_shell = std::make_shared<LabelVolume>(*labels);
  AddShells(*with_shell);
  ASSERT_EQ(with_shell->derived.size(), 1u) << "one shell: the voxels touching label 1";
  EXPECT_EQ(with_shell->derived[0].touches, (std::vector<std::uint16_t>{1}));

  // First hits nearer ball A than ball B (world x < 0: voxel x < 16), at 48x48.
  auto hits_on_a = [&](const std::shared_ptr<const LabelVolume>& l) {
    CpuRenderer r;
    r.SetVolume(volume);
    TransferFunction tf;
    tf.points = {{400, 0, {0.8f, 0.8f, 0.8f}, {}, 0.5f, {}}, {450, 1, {0.8f, 0.8f, 0.8f}, {}, 0.5f, {}}};
    tf.density_scale = 5;
    r.SetTransferFunction(tf);
    r.SetLights(UniformSky(1.0f));
    LabelSetup hide;
    hide.styles[1].visible = false;
    r.SetLabels(l, hide);
    r.Render(Request(LookAt({0, -200, 0}, {0, 0, 0}, {0, 0, 1}, 30.0f, 48, 48), 8, 0, 2));
    int on_a = 0, on_b = 0;
    for (const Vec4f& h : r.FirstHits()) {
      if (h.w == 0) continue;
      (h.x < 0 ? on_a : on_b) += 1;
    }
    EXPECT_GT(on_b, 20) << "ball B shows";
    return on_a;
  };
  EXPECT_GT(hits_on_a(labels), 10) << "without its shell, ball A's rim shows";
  EXPECT_EQ(hits_on_a(with_shell), 0) << "with it, nothing of ball A";
}

// FrameTargets::surface_normal, asked for: on an opaque ball seen along +y
// the nearest first hits' gradients face the eye, and the ball's left rim
// faces left; the medium inside a ball of soft tissue (no surface) gives 0.
// Not asked for, the renderer writes none.
TEST(Integrator, SurfaceNormalsFaceTheEyeWhereTheyAreAskedFor) {
  CpuRenderer r;
  r.SetVolume(testing::Ball());
  r.SetTransferFunction(testing::BallSurface());
  r.SetLights(UniformSky(1.0f));
  const int size = 48;
  FrameRequest request = Request(LookAt({0, -200, 0}, {0, 0, 0}, {0, 0, 1}, 30.0f, size, size), 2, 0, 2);
  r.Render(request);
  EXPECT_TRUE(r.SurfaceNormals().empty()) << "written though not asked for";

  request.surface_normals = true;
  r.Render(request);
  const std::vector<Vec3f> normals = r.SurfaceNormals();
  ASSERT_EQ(normals.size(), std::size_t(size * size));
  const std::vector<Vec4f> hits = r.FirstHits();
  const Vec3f centre = normals[(size / 2) * size + size / 2], rim = normals[(size / 2) * size + size / 2 - 9];
  ASSERT_NE(hits[(size / 2) * size + size / 2 - 9].w, 0.0f) << "the rim pixel must see the ball";
  EXPECT_LT(centre.y, -0.8f) << "the ball's front faces the eye (at -y)";
  EXPECT_LT(Normalize(rim).x, -0.6f) << "the left rim faces left";
  for (int i = 0; i < size * size; ++i) {
    ASSERT_LE(Length(normals[i]), 1.0001f) << "pixel " << i;
    if (hits[i].w == 0.0f) {
      EXPECT_EQ(Length(normals[i]), 0.0f) << "escaped pixel " << i;
    }
  }

  r.SetTransferFunction(testing::BallSurface(0.0f));  // the phase function alone: no surfaces
  r.Render(request);
  for (const Vec3f& normal : r.SurfaceNormals()) ASSERT_EQ(Length(normal), 0.0f);
}

TEST(Integrator, WhiteFurnaceConservesEnergy) {
  for (float tau : {1e-3f, 0.1f, 1.0f, 10.0f}) {
    CpuRenderer r;
    r.SetVolume(UniformCube(16, 2.0f));
    r.SetTransferFunction(ConstantMedium(tau / 32.0f, 1.0f));
    r.SetLights(UniformSky(1.0f));
    const Stats s = RenderStats(r, AxisCamera(), 16, 12, 256);
    EXPECT_NEAR(s.mean, 1.0, std::max(3 * s.stderr_of_mean, 1e-4)) << "tau " << tau;
    EXPECT_TRUE(s.finite);
  }
}

// Per-pixel means over `frames` frames and their standard errors.
void PixelMeans(CpuRenderer& r, const Camera& camera, int spp, int frames, int max_bounces,
                std::vector<double>& mean, std::vector<double>& stderr_of_mean) {
  const std::size_t n = std::size_t(camera.width) * camera.height;
  std::vector<double> sum(n), sum2(n);
  for (int f = 0; f < frames; ++f) {
    r.Render(Request(camera, spp, f, max_bounces));
    const auto& px = r.Radiance().pixels;
    for (std::size_t i = 0; i < n; ++i) {
      sum[i] += px[i].y;
      sum2[i] += double(px[i].y) * px[i].y;
    }
  }
  mean.resize(n);
  stderr_of_mean.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    mean[i] = sum[i] / frames;
    stderr_of_mean[i] = std::sqrt(std::max(0.0, sum2[i] / frames - mean[i] * mean[i]) / (frames - 1));
  }
}

TEST(Integrator, ThickFurnaceLosesEnergyOnlyToTheBounceLimit) {
  CpuRenderer r;
  r.SetVolume(UniformCube(16, 2.0f));
  r.SetTransferFunction(ConstantMedium(100.0f / 32.0f, 1.0f));  // optical thickness 100
  r.SetLights(UniformSky(1.0f));
  double previous = 0;
  for (int bounces : {4, 16, 64}) {
    std::vector<double> mean, err;
    PixelMeans(r, AxisCamera(8, 8), 8, 8, bounces, mean, err);
    double image = 0;
    for (std::size_t i = 0; i < mean.size(); ++i) {
      ASSERT_TRUE(std::isfinite(mean[i]));
      EXPECT_LE(mean[i], 1.0 + 5 * err[i] + 1e-6) << "pixel " << i << " with " << bounces << " bounces";
      image += mean[i] / mean.size();
    }
    EXPECT_LT(image, 1.0);
    EXPECT_GT(image, previous) << "more bounces lose less";
    previous = image;
  }
}

TEST(Integrator, SameSeedSameImageWhateverTheThreadCount) {
  auto render = [](int threads) {
    RendererOptions options;
    options.cpu_threads = threads;
    CpuRenderer r(options);
    r.SetVolume(UniformCube(16, 2.0f));
    r.SetTransferFunction(ConstantMedium(0.05f, 0.8f, 1.0f));
    r.SetLights(UniformSky(1.0f));
    FrameRequest req;
    req.camera = LookAt({60, -80, 40}, {0, 0, 0}, {0, 0, 1}, 40, 24, 20);
    req.spp = 3;
    req.seed = 11;
    r.Render(req);
    return r.Radiance();
  };
  const ImageRgbF one = render(1), three = render(3);
  ASSERT_EQ(one.pixels.size(), three.pixels.size());
  EXPECT_EQ(std::memcmp(one.pixels.data(), three.pixels.data(), one.pixels.size() * sizeof(Vec3f)), 0);
}

TEST(Integrator, SpecialisedVariantAgreesWithGeneral) {
  // A scene using no optional feature: single scattering, one light, phase only.
  CpuRenderer r;
  r.SetVolume(UniformCube(16, 2.0f));
  r.SetTransferFunction(ConstantMedium(1.0f / 32.0f, 0.9f));
  r.SetLights(UniformSky(1.0f));
  const Camera cam = LookAt({60, -80, 40}, {0, 0, 0}, {0, 0, 1}, 30, 8, 8);
  const Stats special = RenderStats(r, cam, 16, 10, 1);
  EXPECT_EQ(r.last_features(), 0u);
  const Stats general = RenderStats(r, cam, 16, 10, 1, kAllFeatures);
  EXPECT_EQ(r.last_features(), kAllFeatures);
  const double sigma = std::hypot(special.stderr_of_mean, general.stderr_of_mean);
  EXPECT_NEAR(special.mean, general.mean, 4 * sigma);
}

// A GPU volume no texture holds renders with VariantOf(features | kAllFeatures)
// (CudaRenderer::Render): that integrator must read voxels and keep the scene's
// clinical features, or it would fetch from a texture that is not there.
TEST(Integrator, AVolumeWithoutATextureTakesAnIntegratorThatReadsVoxels) {
  for (unsigned features = 0; features <= (kAllFeatures | kClinicalFeatures); ++features) {
    const unsigned promoted = VariantFeatures(VariantOf(features | kAllFeatures));
    EXPECT_FALSE(ReadsTexturesOnly(promoted)) << features;
    EXPECT_EQ(promoted & kClinicalFeatures, features & kClinicalFeatures) << features;
  }
  for (unsigned variant = 0; variant < kIntegratorVariants; ++variant) {
    EXPECT_EQ(ReadsTexturesOnly(VariantFeatures(variant)), variant < kAllFeatures) << variant;
  }
}

TEST(Integrator, EmptySpaceSkippingIsUnbiased) {
  // A sparse volume: bricks skip empty space and tighten bounds, the global
  // majorant does neither; both must converge to the same image.
  v1::Phantom p;
  p.set_kind(v1::Phantom::SPHERE);
  p.set_size(32);
  p.set_spacing(1.0f);
  p.set_radius(9.0f);
  auto sphere = std::make_shared<const Volume>(MakePhantom(p));
  TransferFunction tf = ConstantMedium(0.2f, 0.8f, 1.0f);
  tf.points[0] = {100, 0, {0.8f, 0.8f, 0.8f}, {0.2f, 0.2f, 0.2f}, 0.4f, {}};
  tf.points[1] = {900, 1, {0.8f, 0.8f, 0.8f}, {0.2f, 0.2f, 0.2f}, 0.4f, {}};
  const Camera cam = LookAt({30, -50, 20}, {0, 0, 0}, {0, 0, 1}, 30, 8, 8);
  Stats with_bricks, global;
  for (bool bricks : {true, false}) {
    RendererOptions options;
    options.brick_size = bricks ? 8 : 0;
    CpuRenderer r(options);
    r.SetVolume(sphere);
    r.SetTransferFunction(tf);
    r.SetLights(UniformSky(1.0f));
    (bricks ? with_bricks : global) = RenderStats(r, cam, 16, 16, 4);
  }
  EXPECT_NEAR(with_bricks.mean, global.mean, 4 * std::hypot(with_bricks.stderr_of_mean, global.stderr_of_mean));
}

}  // namespace
}  // namespace cinevol

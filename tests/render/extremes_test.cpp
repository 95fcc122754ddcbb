// Numerics at the extremes: degenerate volumes, cameras and images, and
// extinction up to 1e6 per mm give finite images in bounded time; every
// stage after the loader (quantisation, transfer tables, majorants,
// tricubic, labels, the presets' window) at the values Volume accepts; and
// what bounds a frame's cost (docs/rendering.md, "Values at the extremes").
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <limits>
#include <random>
#include <thread>

#include "core/error.h"
#include "encode/hdr_images.h"
#include "encode/image_codecs.h"
#include "io/reader_cage.h"
#include "render/cpu_renderer.h"
#include "render/integrator.h"
#include "render/prepared_volume.h"
#include "render/renderer.h"
#include "render/scene_data.h"
#include "render_test_scenes.h"
#include "scene/scene_builder.h"
#include "scene/scene_file.h"
#include "support/gpu.h"
#include "support/small_scene.h"
#include "support/test_paths.h"

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

Outcome RenderOnce(std::shared_ptr<const Volume> volume, const TransferFunction& tf, const Camera& camera, int spp = 2,
                   int bounces = 8, Backend backend = Backend::kCpu) {
  const auto r = CreateRenderer(backend);
  r->SetVolume(volume);
  r->SetTransferFunction(tf);
  r->SetLights(AllLights());
  FrameRequest req;
  req.camera = camera;
  req.spp = spp;
  req.max_bounces = bounces;
  const auto start = std::chrono::steady_clock::now();
  r->Render(req);
  Outcome o;
  o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  for (const Vec3f& p : r->Radiance().pixels) o.finite &= IsFinite(p) && MinComponent(p) >= 0.0f;
  for (const Vec4f& h : r->FirstHits()) o.finite &= std::isfinite(h.x) && std::isfinite(h.y) && std::isfinite(h.z);
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

#if CINEVOL_WITH_CUDA
// The extremes above on the GPU, whose arithmetic differs from the CPU's:
// denormals flushed to zero, divisions and square roots approximate
// (server/render/CMakeLists.txt).
TEST(CudaExtremes, DegenerateScenesGiveFiniteImages) {
  CINEVOL_REQUIRE_CUDA();
  const auto on_gpu = [](std::shared_ptr<const Volume> volume, const TransferFunction& tf, const Camera& camera,
                         int bounces = 8) { return RenderOnce(volume, tf, camera, 2, bounces, Backend::kCuda); };
  EXPECT_TRUE(on_gpu(UniformCube(8, 2.0f, 0.0f), EmissiveHybrid(1.0f), Oblique()).finite) << "empty";
  EXPECT_TRUE(on_gpu(UniformCube(1, 10.0f, 1000.0f), EmissiveHybrid(1.0f), Oblique()).finite) << "one voxel";
  EXPECT_TRUE(
      on_gpu(Sphere(32, 2.0f), EmissiveHybrid(0.05f), LookAt({1, 2, 3}, {10, 0, 0}, {0, 0, 1}, 60, 16, 16)).finite)
      << "camera inside";
  EXPECT_TRUE(on_gpu(UniformCube(16, 2.0f, 1000.0f), EmissiveHybrid(1.0f),
                     LookAt({-16, -200, 16}, {-16, 0, 16}, {0, 0, 1}, 2, 16, 16))
                  .finite)
      << "grazing";
  EXPECT_TRUE(
      on_gpu(Sphere(16, 1e-3f), EmissiveHybrid(1.0f), LookAt({0.02f, -0.03f, 0.01f}, {0, 0, 0}, {0, 0, 1}, 40, 16, 16))
          .finite)
      << "spacing 1e-3 mm";
  EXPECT_TRUE(
      on_gpu(Sphere(16, 100.0f), EmissiveHybrid(1e-3f), LookAt({2000, -3000, 1000}, {0, 0, 0}, {0, 0, 1}, 40, 16, 16))
          .finite)
      << "spacing 100 mm";
  for (float density : {1e-30f, 1e3f, 1e6f}) {
    const Outcome o = on_gpu(Sphere(32, 1.0f), EmissiveHybrid(density), Oblique(), 64);
    EXPECT_TRUE(o.finite) << density;
    EXPECT_LT(o.seconds, 30.0) << "bounded loops: " << density;
  }
  EXPECT_TRUE(on_gpu(Sphere(16, 2.0f), EmissiveHybrid(0.1f), Oblique(1, 1)).finite) << "one pixel";
}
#endif

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

// ---------------------------------------------------------------------------
// Values the renderer can hold: each stage after the loader, at what Volume
// accepts. Volume refuses the rest (tests/core/volume_test.cpp).

constexpr float kFloatMax = std::numeric_limits<float>::max();

struct Extreme {
  std::string name;
  std::shared_ptr<const Volume> volume;
};

std::shared_ptr<const Volume> Grid(Vec3i dims, Vec3f spacing, std::vector<float> values) {
  VolumeMetadata meta;
  meta.source = "extreme";
  return std::make_shared<const Volume>(dims, spacing, std::move(values), std::move(meta));
}

// A ball of `inside` in `outside`, with an edge a voxel wide, filling most of
// `dims`: surfaces, gradients and empty bricks all exist.
std::shared_ptr<const Volume> Ball(Vec3i dims, Vec3f spacing, double outside, double inside) {
  std::vector<float> values(std::size_t(dims.x) * dims.y * dims.z);
  const Vec3f centre = ToFloat(dims) * 0.5f;
  const float radius = 0.3f * float(std::max({dims.x, dims.y, dims.z}));
  std::size_t i = 0;
  for (int z = 0; z < dims.z; ++z) {
    for (int y = 0; y < dims.y; ++y) {
      for (int x = 0; x < dims.x; ++x, ++i) {
        const float d = Length(Vec3f{x + 0.5f, y + 0.5f, z + 0.5f} - centre);
        const double f = std::clamp(double(radius + 0.5f - d), 0.0, 1.0);
        values[i] = float(outside + (inside - outside) * f);
      }
    }
  }
  return Grid(dims, spacing, std::move(values));
}

std::shared_ptr<const Volume> Constant(Vec3i dims, float value) {
  return Grid(dims, {1, 1, 1}, std::vector<float>(std::size_t(dims.x) * dims.y * dims.z, value));
}

// Subnormals (flushed to 0) beside the smallest normal floats: the narrowest
// range a volume can have above zero, 2.4e-38 wide.
std::shared_ptr<const Volume> Subnormal() {
  std::vector<float> values(8 * 8 * 8);
  for (std::size_t i = 0; i < values.size(); ++i) {
    values[i] =
        i % 3 == 0 ? 1e-40f : (i % 3 == 1 ? std::numeric_limits<float>::min() : 2 * std::numeric_limits<float>::min());
  }
  return Grid({8, 8, 8}, {1, 1, 1}, std::move(values));
}

std::vector<Extreme> Extremes() {
  const float m = kMaxVoxelMagnitude;
  return {
      {"values -1e30 to 1e30", Ball({8, 8, 8}, {1, 1, 1}, -m, m)},
      {"1e30 on 0", Ball({8, 8, 8}, {1, 1, 1}, 0, m)},
      {"subnormals", Subnormal()},
      {"constant 5", Constant({8, 8, 8}, 5.0f)},
      {"constant 0.5", Constant({8, 8, 8}, 0.5f)},
      {"constant 1e30", Constant({8, 8, 8}, m)},
      {"constant -1e30", Constant({8, 8, 8}, -m)},
      {"one voxel of 1e30", Constant({1, 1, 1}, m)},
      {"one voxel of 7", Constant({1, 1, 1}, 7.0f)},
      {"1x16x1", Ball({1, 16, 1}, {1, 1, 1}, -1000, 3000)},
      {"16x1x1", Ball({16, 1, 1}, {1, 1, 1}, -1000, 3000)},
      {"1x1x16 of +-1e30", Ball({1, 1, 16}, {1, 1, 1}, -m, m)},
      {"spacing 1e-3 mm", Ball({8, 8, 8}, {1e-3f, 1e-3f, 1e-3f}, -1000, 3000)},
      {"spacing 1e3 mm", Ball({8, 8, 8}, {1e3f, 1e3f, 1e3f}, -1000, 3000)},
      {"spacing 1e4 mm, the largest", Ball({8, 8, 8}, {1e4f, 1e4f, 1e4f}, 0, m)},
      {"spacing 1e-3 x 1 x 1e3 mm", Ball({8, 8, 8}, {1e-3f, 1.0f, 1e3f}, -1000, 3000)},
  };
}

// The transfer functions each volume is seen through: the default preset on
// the histogram's window, the same at the largest density validation takes
// with a gradient factor of FLT_MAX, and a ramp whose points lie at
// -+FLT_MAX.
std::vector<std::pair<std::string, TransferFunction>> TransferFunctions(const Volume& volume) {
  TransferFunction preset = ResolveTransferFunction(v1::TransferFunction(), volume);
  TransferFunction dense = preset;
  dense.density_scale = 1e6f;
  dense.gradient_factor = kFloatMax;
  TransferFunction widest;
  widest.points = {{-kFloatMax, 0.0f, {1, 1, 1}, {1, 1, 1}, 0.0f, {}},
                   {kFloatMax, 1.0f, {1, 0, 0}, {0, 0, 0}, 1.0f, {1, 1, 1}}};
  widest.density_scale = 1e6f;
  widest.gradient_factor = 1.0f;
  return {{"preset", preset}, {"preset at density 1e6", dense}, {"points at +-FLT_MAX", widest}};
}

// A camera that frames the volume, whatever its size.
Camera Framing(const Volume& volume, int width = 16, int height = 12) {
  const float radius = 0.5f * Length(volume.extent_mm());
  return LookAt(Normalize(Vec3f{0.7f, -0.9f, 0.5f}) * (3.0f * radius), {0, 0, 0}, {0, 0, 1}, 40, width, height);
}

// A segmentation of the volume's grid: labels 0, 1 and 2 in turn; 1 at the
// largest opacity scale validation takes, 2 with the widest transfer function.
std::shared_ptr<const LabelVolume> Stripes(const Volume& volume) {
  auto labels = std::make_shared<LabelVolume>();
  labels->dims = volume.dims();
  labels->labels.resize(volume.voxel_count());
  for (std::size_t i = 0; i < labels->labels.size(); ++i) {
    labels->labels[i] = std::uint16_t(i % 3);
    ++labels->voxels[labels->labels[i]];
  }
  return labels;
}

LabelSetup StripeStyles(const Volume& volume) {
  LabelSetup setup;
  setup.styles[1].opacity_scale = 1000.0f;
  setup.styles[2].transfer = 0;
  setup.transfer_functions.push_back(TransferFunctions(volume).back().second);
  return setup;
}

// What the integrator takes as extinction at p.
float ExtinctionAt(const RenderScene& s, Vec3f p) {
  const float entry = s.transfer.Entry(s.volume.Sample(p));
  if (!s.labels.voxels) return s.transfer.SigmaT(entry);
  const LabelMaterial m = s.labels.At(s.volume, p);
  return std::min(m.opacity_scale * s.transfer.SigmaT(entry, m.table), s.transfer.max_sigma_t);
}

// Quantisation: 16-bit levels over the volume's range with a normal,
// finite step, and every value back to within half a step.
void ExpectQuantisedFaithfully(const PreparedVolume& p) {
  const Volume& v = p.volume();
  ASSERT_TRUE(std::isfinite(p.value_scale()) && std::isfinite(p.value_offset()));
  ASSERT_GE(p.value_scale(), std::numeric_limits<float>::min());
  const double tolerance = 0.5 * double(p.value_scale()) * (1 + 1e-5) +
                           1e-6 * std::max(std::abs(double(v.min_value())), std::abs(double(v.max_value())));
  for (std::size_t i = 0; i < v.voxel_count(); ++i) {
    const double back = double(p.voxels()[i]) * p.value_scale() + p.value_offset();
    ASSERT_NEAR(back, v.ValueAtIndex(i), tolerance) << "voxel " << i;
  }
}

// Tables and majorants: finite, within the extinction clamp, and never
// below the extinction at any point (trilinear or tricubic, with labels).
void ExpectTablesBoundExtinction(const SceneData& data) {
  const RenderScene s = data.HostView();
  ASSERT_TRUE(std::isfinite(s.transfer.entry_scale) && std::isfinite(s.transfer.entry_offset));
  ASSERT_TRUE(std::isfinite(s.transfer.gradient_normaliser) && s.transfer.gradient_normaliser >= 0.0f);
  ASSERT_TRUE(std::isfinite(s.transfer.max_sigma_t) && s.transfer.max_sigma_t > 0.0f);
  ASSERT_LE(s.transfer.gradient_factor, kMaxGradientFactor);
  for (const float stored : {0.0f, 65535.0f})
    ASSERT_TRUE(std::isfinite(stored * s.transfer.entry_scale + s.transfer.entry_offset));
  const TransferTable& t = data.table();
  for (std::size_t i = 0; i < t.sigma_t.size(); ++i) {
    ASSERT_TRUE(std::isfinite(t.sigma_t[i]) && t.sigma_t[i] >= 0.0f) << "entry " << i;
    ASSERT_LE(t.sigma_t[i], s.transfer.max_sigma_t);
    ASSERT_TRUE(IsFinite(Xyz(t.diffuse_opacity[i])) && std::isfinite(t.diffuse_opacity[i].w)) << "entry " << i;
    ASSERT_TRUE(IsFinite(Xyz(t.emission[i]))) << "entry " << i;
  }
  for (const float m : data.majorants()) {
    ASSERT_TRUE(std::isfinite(m) && m >= 0.0f);
    ASSERT_LE(m, s.transfer.max_sigma_t);
  }
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int k = 0; k < 2000; ++k) {
    const Vec3f p = s.volume.box_min + (s.volume.box_max - s.volume.box_min) * Vec3f{u(rng), u(rng), u(rng)};
    const float stored = s.volume.Sample(p);
    ASSERT_TRUE(std::isfinite(stored) && stored >= -0.1f && stored <= 65535.1f)
        << stored;  // B-spline weights sum to 1 within rounding
    Vec3i b;
    for (int a = 0; a < 3; ++a) {
      b[a] = std::clamp(int((p[a] - s.majorants.box_min[a]) * s.majorants.inv_brick_size[a]), 0,
                        s.majorants.bricks[a] - 1);
    }
    ASSERT_LE(ExtinctionAt(s, p), s.majorants.At(b));
  }
}

Outcome RenderExtreme(const std::shared_ptr<const Volume>& volume, const TransferFunction& tf, Reconstruction r,
                      const std::shared_ptr<const LabelVolume>& labels) {
  CpuRenderer renderer;
  renderer.SetVolume(volume);
  renderer.SetTransferFunction(tf);
  renderer.SetReconstruction(r);
  if (labels) renderer.SetLabels(labels, StripeStyles(*volume));
  renderer.SetLights(AllLights());
  FrameRequest req;
  req.camera = Framing(*volume);
  req.spp = 2;
  req.max_bounces = 8;
  const auto start = std::chrono::steady_clock::now();
  renderer.Render(req);
  Outcome o;
  o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  for (const Vec3f& p : renderer.Radiance().pixels) o.finite &= IsFinite(p) && MinComponent(p) >= 0.0f;
  for (const Vec4f& h : renderer.FirstHits())
    o.finite &= std::isfinite(h.x) && std::isfinite(h.y) && std::isfinite(h.z);
  for (const Vec3f& a : renderer.Albedo().pixels) o.finite &= IsFinite(a);
  return o;
}

TEST(ValuesAtTheExtremes, QuantisationKeepsEveryValueWithinHalfAStep) {
  for (const Extreme& e : Extremes()) {
    SCOPED_TRACE(e.name);
    ExpectQuantisedFaithfully(PreparedVolume(e.volume, kDefaultBrickSize));
    ExpectQuantisedFaithfully(PreparedVolume(e.volume, 0));  // one brick
  }
}

TEST(ValuesAtTheExtremes, PresetsFindAWindowOnEveryHistogram) {
  for (const Extreme& e : Extremes()) {
    SCOPED_TRACE(e.name);
    const ValueWindow w = AutoWindow(e.volume->histogram());
    EXPECT_TRUE(std::isfinite(w.lo) && std::isfinite(w.hi));
    EXPECT_LT(w.lo, w.hi);
    const TransferFunction tf = ResolveTransferFunction(v1::TransferFunction(), *e.volume);
    ASSERT_FALSE(tf.points.empty());
    for (std::size_t i = 1; i < tf.points.size(); ++i) EXPECT_GT(tf.points[i].value, tf.points[i - 1].value);
    for (const TransferPoint& p : tf.points) EXPECT_TRUE(std::isfinite(p.value));
  }
}

TEST(ValuesAtTheExtremes, TransferTablesAndMajorantsStayFiniteAndBoundExtinction) {
  for (const Extreme& e : Extremes()) {
    for (const auto& [tf_name, tf] : TransferFunctions(*e.volume)) {
      for (const Reconstruction r : {Reconstruction::kTrilinear, Reconstruction::kTricubic}) {
        for (const bool with_labels : {false, true}) {
          SCOPED_TRACE(e.name + ", " + tf_name + (r == Reconstruction::kTricubic ? ", tricubic" : ", trilinear") +
                       (with_labels ? ", labels" : ""));
          SceneData data;
          data.SetVolume(std::make_shared<const PreparedVolume>(e.volume, kDefaultBrickSize));
          data.SetReconstruction(r);
          data.SetTransferFunction(tf);
          if (with_labels) {
            data.SetLabels(
                VolumeCache::Get().AcquireLabels(Stripes(*e.volume), data.volume().brick_size(), kHostDevice),
                StripeStyles(*e.volume));
          }
          ExpectTablesBoundExtinction(data);
        }
      }
    }
  }
}

TEST(ValuesAtTheExtremes, FramesAreFiniteInBoundedTime) {
  for (const Extreme& e : Extremes()) {
    for (const auto& [tf_name, tf] : TransferFunctions(*e.volume)) {
      for (const Reconstruction r : {Reconstruction::kTrilinear, Reconstruction::kTricubic}) {
        for (const bool with_labels : {false, true}) {
          const std::string what = e.name + ", " + tf_name + (r == Reconstruction::kTricubic ? ", tricubic" : "") +
                                   (with_labels ? ", labels" : "");
          const Outcome o = RenderExtreme(e.volume, tf, r, with_labels ? Stripes(*e.volume) : nullptr);
          EXPECT_TRUE(o.finite) << what;
          EXPECT_LT(o.seconds, 10.0) << what;  // 16x12 at 2 spp: milliseconds
        }
      }
    }
  }
}

// A transfer function's points may lie as far apart as float reaches: the
// interpolation between them is still right (b - a overflows in float).
TEST(ValuesAtTheExtremes, PointsAtFloatMaxInterpolate) {
  TransferFunction tf;
  tf.points = {{-kFloatMax, 0.0f, {}, {}, 0.0f, {}}, {kFloatMax, 1.0f, {}, {}, 1.0f, {}}};
  EXPECT_NEAR(Evaluate(tf, 0.0f).opacity, 0.5f, 1e-6f);
  EXPECT_NEAR(Evaluate(tf, kMaxVoxelMagnitude).opacity, 0.5f, 1e-6f);
  EXPECT_NEAR(Evaluate(tf, kFloatMax / 2).opacity, 0.75f, 1e-6f);
  EXPECT_EQ(Evaluate(tf, -kFloatMax).opacity, 0.0f);
}

// Extinction is clamped at kMaxOpticalDepthPerVoxel per voxel: a density
// scale of 1e6 on a 1 mm grid gives the tables 32 per mm, not 1e6.
TEST(ValuesAtTheExtremes, ExtinctionIsClampedPerVoxel) {
  for (const float spacing : {1e-3f, 1.0f, 1e3f}) {
    SceneData data;
    data.SetVolume(std::make_shared<const PreparedVolume>(Ball({16, 16, 16}, {spacing, spacing, spacing}, 0, 1000),
                                                          kDefaultBrickSize));
    data.SetTransferFunction(ConstantMedium(1e6f, 0.5f));
    const float clamp = kMaxOpticalDepthPerVoxel / spacing;
    EXPECT_FLOAT_EQ(data.HostView().transfer.max_sigma_t, clamp);
    EXPECT_FLOAT_EQ(*std::max_element(data.majorants().begin(), data.majorants().end()), std::min(1e6f, clamp));
  }
}

// Environment rotations are taken within one turn: any finite one keeps the
// map's lookups inside it.
TEST(ValuesAtTheExtremes, AnyFiniteEnvironmentRotationReadsTheMap) {
  LightSetup lights;
  lights.environment.kind = Environment::Kind::kMap;
  lights.environment.map = {4, 2, std::vector<Vec3f>(8, Vec3f{0.5f, 0.5f, 0.5f})};
  for (const float rotation : {kFloatMax, -kFloatMax, 1e30f, 7.0f}) {
    lights.environment.rotation = rotation;
    CpuRenderer r;
    r.SetVolume(Sphere(16, 2.0f));
    r.SetTransferFunction(EmissiveHybrid(0.05f));
    r.SetLights(lights);
    FrameRequest req;
    req.camera = Oblique();
    req.spp = 2;
    r.Render(req);
    for (const Vec3f& p : r.Radiance().pixels) ASSERT_TRUE(IsFinite(p)) << rotation;
  }
}

// An environment map through the scene: a rotation of FLT_MAX degrees (in
// radians it overflows float, and the texel index it gave was INT_MIN) and
// texels past the radiance limit once scaled by the intensity.
TEST(ValuesAtTheExtremes, EnvironmentMapsAtTheExtremesResolveToFiniteLight) {
  testing::ScratchDir dir;
  ImageRgbF map{4, 2, std::vector<Vec3f>(8, Vec3f{0.5f, 0.5f, 0.5f})};
  map.pixels[3] = {65504.0f, 0.0f, 1.0f};
  WriteExr(dir / "sky.exr", map);
  for (const float degrees : {kFloatMax, -kFloatMax, 1e30f, 725.0f}) {
    v1::Scene scene;
    v1::EnvironmentLight* sky = scene.add_lights()->mutable_environment();
    sky->set_map((dir / "sky.exr").string());
    sky->set_rotation_deg(degrees);
    sky->set_intensity(kMaxRadiance);
    const LightSetup lights = ResolveLights(scene.lights(), [](const std::string& map) { return reader_cage::ReadEnvironmentMap(map); });
    ASSERT_EQ(lights.environment.kind, Environment::Kind::kMap);
    EXPECT_LE(std::abs(lights.environment.rotation), kPi) << degrees;
    if (degrees == 725.0f) {
      EXPECT_NEAR(lights.environment.rotation, 5.0f * kPi / 180.0f, 1e-6f);
    }
    for (const Vec3f& p : lights.environment.map.pixels) {
      ASSERT_TRUE(IsFinite(p) && MinComponent(p) >= 0.0f && MaxComponent(p) <= kMaxRadiance) << degrees;
    }
    CpuRenderer r;
    r.SetVolume(Sphere(16, 2.0f));
    r.SetTransferFunction(EmissiveHybrid(0.05f));
    r.SetLights(lights);
    FrameRequest req;
    req.camera = Oblique();
    req.spp = 2;
    r.Render(req);
    for (const Vec3f& p : r.Radiance().pixels) ASSERT_TRUE(IsFinite(p)) << degrees;
  }
}

// ---------------------------------------------------------------------------
// What a frame costs: the extinction clamp keeps a density scale of 1e6 to
// what a dense volume costs, every path has a budget of collisions, and a
// cancel is seen within a pixel.

// Collisions over every path of a frame, traced as RenderPixel traces them.
struct FrameCost {
  double mean_per_path = 0;
  int max_per_path = 0;
  int budget_ends = 0;
};

FrameCost CostOf(const SceneData& data, const Camera& camera, int spp, int max_bounces) {
  RenderScene s = data.HostView();
  FrameRequest req;
  req.camera = camera;
  req.spp = spp;
  req.max_bounces = max_bounces;
  ApplyRequest(req, s);
  FrameCost cost;
  double total = 0;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      for (int k = 0; k < spp; ++k) {
        Pcg32 rng(HashCombine(y, x), std::uint64_t(k));
        PathTracer<kAllFeatures> tracer(s, rng);
        tracer.Trace(camera.GenerateRay(x + rng.Uniform(), y + rng.Uniform(), 0.5f, 0.5f));
        total += tracer.collisions();
        cost.max_per_path = std::max(cost.max_per_path, tracer.collisions());
        cost.budget_ends += tracer.budget_ends();
      }
    }
  }
  cost.mean_per_path = total / (double(camera.width) * camera.height * spp);
  return cost;
}

// The frame: 64x48 of the head through ct-bone at density scale 1e6
// took 33 s on a 2-core CPU, where the preset's density took 1 s: paths
// crossed bricks of majorant 1e6 per mm, a million tentative collisions a
// millimetre. Clamped, they cost what the clamp's density costs.
TEST(FrameCost, ADensityScaleOfAMillionCostsWhatTheClampAllows) {
  const auto head = testing::SmallHead();
  const v1::Scene scene = testing::SmallScene(*head, 64, 48, 2);
  const RenderSetup setup = ResolveScene(scene, *head, nullptr);
  auto cost_at = [&](float density) {
    SceneData data;
    data.SetVolume(std::make_shared<const PreparedVolume>(head, kDefaultBrickSize));
    TransferFunction tf = setup.transfer_function;
    tf.density_scale = density;
    data.SetTransferFunction(tf);
    data.SetLights(setup.lights);
    return CostOf(data, setup.camera, 2, 4);
  };
  const float clamp = MaxExtinction(head->spacing_mm());
  const FrameCost preset = cost_at(setup.transfer_function.density_scale);
  const FrameCost at_clamp = cost_at(clamp);
  const FrameCost million = cost_at(1e6f);
  EXPECT_EQ(million.budget_ends, 0);
  EXPECT_LE(million.mean_per_path, 1.5 * at_clamp.mean_per_path) << "above the clamp, density adds little";
  EXPECT_LT(million.mean_per_path, 5 * std::max(1.0, preset.mean_per_path))
      << "preset " << preset.mean_per_path << ", density 1e6 " << million.mean_per_path;
  EXPECT_LT(million.max_per_path, kMaxPathCollisions);
}

// However dense and however thin what a path crosses, it takes at most
// kMaxPathCollisions tentative collisions, over all its tracking calls.
TEST(FrameCost, APathStopsAtItsCollisionBudget) {
  std::vector<float> majorant{1e6f};
  const MajorantGridView grid{majorant.data(), {1, 1, 1}, {-50, -50, -50}, {0.01f, 0.01f, 0.01f}};
  Pcg32 rng(1, 2);
  int budget = 1000, calls = 0;
  auto never_real = [&](float, float) {
    ++calls;
    return true;
  };
  EXPECT_EQ(SampleMajorant(grid, {-50, 0, 0}, {1, 0, 0}, 0.0f, 100.0f, rng, budget, never_real),
            TrackResult::kBudgetExhausted);
  EXPECT_EQ(calls, 1000);
  // A shadow ray of the same path has nothing left.
  EXPECT_EQ(SampleMajorant(grid, {0, -50, 0}, {0, 1, 0}, 0.0f, 100.0f, rng, budget, never_real),
            TrackResult::kBudgetExhausted);
  EXPECT_EQ(calls, 1000);
  // Empty space costs no collisions, so nothing from the budget.
  majorant[0] = 0.0f;
  EXPECT_EQ(SampleMajorant(grid, {-50, 0, 0}, {1, 0, 0}, 0.0f, 100.0f, rng, budget, never_real),
            TrackResult::kLeftRange);
}

// Far from the ray's origin a step of 1e-4 mm is below t's precision (at
// t = 1e5 mm floats are 0.008 mm apart): steps still add up, so a 2 mm box
// at 1e4 per mm costs its 2e4 expected collisions, not the whole budget.
TEST(FrameCost, FreeFlightsFarFromTheOriginStillAdvance) {
  std::vector<float> majorant{1e4f};
  const MajorantGridView grid{majorant.data(), {1, 1, 1}, {-1, -1, -1}, {0.5f, 0.5f, 0.5f}};
  Pcg32 rng(3, 4);
  int budget = kMaxPathCollisions, calls = 0;
  const Vec3f o{-1e5f, 0, 0}, d{1, 0, 0};
  float t0, t1;
  ASSERT_TRUE(IntersectBox(o, {1, 1e30f, 1e30f}, {-1, -1, -1}, {1, 1, 1}, t0, t1));
  EXPECT_EQ(SampleMajorant(grid, o, d, t0, t1, rng, budget, [&](float t, float) {
              ++calls;
              return t >= t0 && t <= t1;
            }),
            TrackResult::kLeftRange);
  EXPECT_NEAR(calls, 2e4, 5 * std::sqrt(2e4) + 2e4 * 0.01);  // Poisson; t1 - t0 rounds by an ulp
}

// A raised cancel is seen before the next pixel: a single row (one thread,
// which used to look at the flag once per row) stops part way. The row holds
// seconds of work even on a fast machine, so the cancel at 50 ms always lands
// inside it.
TEST(FrameCost, ACancelStopsTheFrameWithinAPixel) {
  CpuRenderer r;
  r.SetVolume(Sphere(32, 2.0f));
  r.SetTransferFunction(EmissiveHybrid(0.05f));
  r.SetLights(AllLights());
  std::atomic<bool> cancel{false};
  FrameRequest req;
  req.camera = LookAt({70, -90, 50}, {0, 0, 0}, {0, 0, 1}, 40, 2048, 1);
  req.spp = 16384;
  req.max_bounces = 16;
  req.cancel = &cancel;
  std::thread raise([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    cancel = true;
  });
  const auto start = std::chrono::steady_clock::now();
  EXPECT_THROW(r.Render(req), Cancelled);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  raise.join();
  int rendered = 0;
  for (const Vec3f& p : r.Radiance().pixels) rendered += MaxComponent(p) > 0.0f;
  EXPECT_LT(rendered, 2048) << "the row ran to its end";
  EXPECT_LT(seconds, 5.0);
}

}  // namespace
}  // namespace cinevol

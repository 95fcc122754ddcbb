// A second volume fused with the scene's (issue 59), against analytic answers:
// an emitting PET-like sphere inside an absorbing CT-like cube, on a grid of
// its own (finer, offset, mirrored), renders the closed form of the two mixed
// media; a pick answers both volumes' values at the right positions; a slice
// draws the second volume through its colour map where it lies.
#include <gtest/gtest.h>

#include <cmath>

#include "reading/pick.h"
#include "reading/slice.h"
#include "render/cpu_renderer.h"
#include "render_test_scenes.h"
#include "scene/scene_builder.h"

namespace cinevol {
namespace {

using testing::AxisCamera;
using testing::ConstantMedium;
using testing::UniformCube;

// A volume of `dims` voxels of `spacing` mm placed with `direction` and
// `origin` (LPS), each voxel's value f(its LPS centre).
template <class F>
std::shared_ptr<const Volume> VolumeOf(Vec3i dims, float spacing, std::array<double, 9> direction,
                                       std::array<double, 3> origin, F f) {
  VolumeMetadata meta;
  meta.source = "fusion test";
  meta.direction = direction;
  meta.origin_mm = origin;
  std::vector<float> values(std::size_t(dims.x) * dims.y * dims.z);
  for (int z = 0; z < dims.z; ++z) {
    for (int y = 0; y < dims.y; ++y) {
      for (int x = 0; x < dims.x; ++x) {
        Vec3f lps;
        for (int r = 0; r < 3; ++r) {
          lps[r] =
              float(origin[r] + spacing * (direction[3 * r] * x + direction[3 * r + 1] * y + direction[3 * r + 2] * z));
        }
        values[(std::size_t(z) * dims.y + y) * dims.x + x] = f(lps);
      }
    }
  }
  return std::make_shared<const Volume>(dims, Vec3f{spacing, spacing, spacing}, std::move(values), meta);
}

constexpr std::array<double, 9> kIdentity{1, 0, 0, 0, 1, 0, 0, 0, 1};
constexpr std::array<double, 9> kMirroredX{-1, 0, 0, 0, 1, 0, 0, 0, 1};

// Emission only (no bounce, no light): a pixel's radiance is the emission of
// the first collision, which meets the sphere's medium with its share of the
// summed extinction. Along a chord of 2h through the sphere's middle of a
// cube of half-chord c: e^(-s1 (c - h)) s2 / (s1 + s2) (1 - e^(-(s1 + s2) 2h)).
TEST(Fusion, AnEmittingSphereInAnAbsorbingCubeRendersTheClosedForm) {
  const auto cube = UniformCube(16, 2.0f);  // 32 mm across, centred on the patient's origin
  const float s1 = 0.5f / 32, s2 = 0.1f, radius = 10;
  // The sphere on a grid of its own: 0.25 mm voxels over 22 mm, mirrored in x.
  const int n = 88;
  const double half = (n - 1) * 0.25 / 2;
  const auto sphere = VolumeOf({n, n, n}, 0.25f, kMirroredX, {half, -half, -half},
                               [&](Vec3f p) { return Length(p) <= radius ? 1.0f : 0.0f; });
  v1::Fusion fusion;
  fusion.set_volume_id("sphere");
  v1::TransferFunction& tf = *fusion.mutable_transfer_function();
  for (float value : {0.0f, 1.0f}) {
    v1::TransferFunctionPoint& point = *tf.add_points();
    point.set_value(value);
    point.set_opacity(value);
    point.mutable_emission()->set_r(value);
    point.mutable_emission()->set_g(value);
    point.mutable_emission()->set_b(value);
  }
  tf.set_density_scale(s2);
  CpuRenderer r;
  r.SetVolume(cube);
  r.SetTransferFunction(ConstantMedium(s1, 0.0f));
  r.SetLights({});
  r.SetFusion(sphere, ResolveFusion(fusion, *cube, *sphere));

  // 7 mm across the middle: chords change slowly over a pixel's footprint.
  const Camera camera = AxisCamera(16, 16, 4000.0f, 0.1f);
  FrameRequest request;
  request.camera = camera;
  request.spp = 256;
  request.max_bounces = 0;
  double rendered = 0, expected = 0;
  const int frames = 8;
  for (int f = 0; f < frames; ++f) {
    request.frame = std::uint32_t(f);
    r.Render(request);
  }
  EXPECT_TRUE(r.last_features() & kFusion);
  const ImageRgbF image = r.AccumulatedMean();
  for (int y = 0; y < 16; ++y) {
    for (int x = 0; x < 16; ++x) {
      const Ray ray = camera.GenerateRay(x + 0.5f, y + 0.5f, 0.5f, 0.5f);
      const Vec3f at = ray.origin + ray.direction * (-ray.origin.y / ray.direction.y);  // where it crosses y = 0
      const double h = std::sqrt(std::max(0.0, double(radius) * radius - at.x * at.x - at.z * at.z));
      expected += std::exp(-s1 * (16 - h)) * s2 / (s1 + s2) * (1 - std::exp(-(s1 + s2) * 2 * h)) / 256;
      rendered += image.pixels[std::size_t(y) * 16 + x].y / 256;
    }
  }
  // 256 pixels x 2048 paths, each 0 or 1: the mean's standard error is below 0.001.
  EXPECT_NEAR(rendered, expected, 0.01 * expected + 0.003) << "expected " << expected;
  EXPECT_GT(expected, 0.5);
}

// Two volumes on offset grids: a pick on the first's surface answers its
// value there and the second's, each a linear function of the position, so
// trilinear sampling on either grid gives it exactly.
TEST(Fusion, APickAnswersBothVolumesAtTheRightPositions) {
  auto ramp = [](Vec3f p) { return 2 * p.x + 3 * p.y - p.z + 7; };
  const auto ct = VolumeOf({40, 40, 40}, 1.0f, kIdentity, {-19.5, -19.5, -19.5}, [](Vec3f p) { return p.x + 100; });
  // Coarser, offset by a third of a voxel, mirrored, and larger than the first.
  const auto pet = VolumeOf({30, 30, 30}, 2.0f, kMirroredX, {29.3, -29.7, -29.0}, ramp);
  RenderSetup setup;
  setup.transfer_function = ConstantMedium(5.0f, 0.5f);
  setup.camera = LookAt({0, -300, 0}, {0, 0, 0}, {0, 0, 1}, 10, 33, 33);
  setup.fused_volume = pet;
  v1::Fusion fusion;
  fusion.set_volume_id("pet");
  setup.fusion = ResolveFusion(fusion, *ct, *pet);
  const Picker picker(ct, nullptr, setup);
  int hits = 0;
  for (const auto& [x, y] : {std::pair{16, 16}, {8, 10}, {24, 20}, {12, 26}}) {
    const PickResult hit = picker.PickPixel(x, y);
    ASSERT_TRUE(hit.hit) << x << ", " << y;
    ++hits;
    EXPECT_NEAR(hit.value, hit.position_lps.x + 100, 1e-2) << x << ", " << y;
    ASSERT_TRUE(hit.fused_value.has_value());
    EXPECT_NEAR(*hit.fused_value, ramp(hit.position_lps), 1e-2) << x << ", " << y;
  }
  EXPECT_EQ(hits, 4);
}

// A slice draws the second volume where it lies, through the hot colour map
// from the window's bottom; elsewhere the first volume's grey stays.
TEST(Fusion, ASliceOverlaysTheSecondVolumeThroughItsColourMap) {
  const auto ct = VolumeOf({32, 32, 8}, 1.0f, kIdentity, {-15.5, -15.5, -3.5}, [](Vec3f) { return 50.0f; });
  const auto pet = VolumeOf({16, 16, 8}, 0.5f, kIdentity, {-3.75, -3.75, -1.75}, [](Vec3f) { return 4.0f; });
  SliceSpec spec;
  spec.axis = SliceAxis::kAxial;
  spec.window = {50, 100};
  spec.fusion.volume = pet.get();
  spec.fusion.lowest = 0;
  spec.fusion.width = 6;  // 4 is two thirds up the hot map: full red, full green, no blue
  spec.fusion.opacity = 1;
  const SliceImage slice = RenderSlice(*ct, {}, nullptr, spec);
  SliceSpec plain_spec = spec;
  plain_spec.fusion = {};
  const SliceImage plain = RenderSlice(*ct, {}, nullptr, plain_spec);
  auto pixel = [](const SliceImage& s, int x, int y) {
    const std::uint8_t* p = &s.image.bytes[3 * (std::size_t(y) * s.image.width + x)];
    return std::array<int, 3>{p[0], p[1], p[2]};
  };
  ASSERT_EQ(slice.image.width, 32);
  EXPECT_EQ(pixel(slice, 16, 16), (std::array<int, 3>{255, 255, 0})) << "inside the second volume";
  EXPECT_EQ(pixel(slice, 2, 2), pixel(plain, 2, 2)) << "the first volume's grey alone";
  spec.fusion.opacity = 0.5f;
  const SliceImage half = RenderSlice(*ct, {}, nullptr, spec);
  EXPECT_EQ(pixel(half, 16, 16)[2], int(pixel(plain, 16, 16)[2] * 0.5f + 0.5f)) << "half way to the map's blue 0";
}

}  // namespace
}  // namespace cinevol

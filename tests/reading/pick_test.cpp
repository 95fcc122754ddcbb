// Picking on the 3D view: where the ray through a pixel stops on analytic
// phantoms (faces, hidden labels, clipping, thresholds), the value it reads
// on a real CT, measurements between picks, and `cinevol pick` end to end.
#include "reading/pick.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <regex>

#include "core/error.h"
#include "io/label_volume.h"
#include "io/phantom.h"
#include "io/volume_loader.h"
#include "reading/measurements.h"
#include "scene/presets.h"
#include "scene/scene_builder.h"
#include "scene/scene_file.h"
#include "service/server_process.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

constexpr float kHalfVoxel = 0.5f;  // the phantoms' voxels are 1 mm
constexpr int kViewport = 65;       // odd: pixel 32's centre is on the axis
constexpr int kCentre = kViewport / 2;

// A 64 mm volume of 1 mm voxels; inside `radius` mm of the centre (a cube's
// half-edge) `value`, outside 0. Its LPS frame is the volume-centred one.
std::shared_ptr<const Volume> CubePhantom(float value = 1000.0f, float radius = 20.0f) {
  v1::Phantom p;
  p.set_kind(v1::Phantom::CUBE);
  p.set_size(64);
  p.set_spacing(1.0f);
  p.set_value(value);
  p.set_background(0.0f);
  p.set_radius(radius);
  return std::make_shared<const Volume>(MakePhantom(p));
}

// Transparent below 400, opaque from 600: a surface halfway between 0 and
// 1000. `density` per mm (clamped by the renderer at 32 per 1 mm voxel).
TransferFunction Surface(float density = 50.0f) {
  TransferFunction tf;
  const Vec3f grey{0.8f, 0.8f, 0.8f};
  tf.points = {{400, 0, grey, {}, 0.5f, {}}, {600, 1, grey, {}, 0.5f, {}}};
  tf.density_scale = density;
  return tf;
}

// Looking at the centre from `eye`, with z up.
RenderSetup Looking(Vec3f eye, TransferFunction tf = Surface()) {
  RenderSetup setup;
  setup.camera = LookAt(eye, {0, 0, 0}, {0, 0, 1}, 20.0f, kViewport, kViewport);
  setup.transfer_function = std::move(tf);
  return setup;
}

PickResult PickCentre(const std::shared_ptr<const Volume>& volume, const RenderSetup& setup,
                      std::shared_ptr<const LabelVolume> labels = nullptr, float threshold = 0.5f) {
  PickSettings settings;
  settings.threshold = threshold;
  return Picker(volume, std::move(labels), setup).PickPixel(kCentre, kCentre, settings);
}

// The cube's segmentation: label 1 "cube" on its voxels, with the shell
// around them that hides with it (as a loaded segmentation has).
std::shared_ptr<const LabelVolume> CubeLabels(const Volume& image) {
  auto labels = std::make_shared<LabelVolume>(FitLabels(*CubePhantom(1.0f), image, "cube labels"));
  labels->names[1] = "cube";
  return labels;
}

TEST(Pick, AtTheCentreOfACubeLandsOnItsFrontFace) {
  const auto cube = CubePhantom();
  const PickResult r = PickCentre(cube, Looking({0, -400, 0}));
  ASSERT_TRUE(r.hit);
  EXPECT_NEAR(r.position_lps.y, -20.0f, kHalfVoxel) << "the front face";
  EXPECT_NEAR(r.position_lps.x, 0.0f, 1e-3f);
  EXPECT_NEAR(r.position_lps.z, 0.0f, 1e-3f);
  EXPECT_NEAR(r.distance_mm, 380.0f, kHalfVoxel);
  EXPECT_GT(r.value, 400.0f) << "where the transfer function starts to show the cube";
  EXPECT_LT(r.value, 1000.0f);
  EXPECT_FALSE(r.label) << "no segmentation";
}

TEST(Pick, TwoPicksOnOppositeFacesMeasureTheCube) {
  const auto cube = CubePhantom();
  const PickResult front = PickCentre(cube, Looking({0, -400, 0}));
  const PickResult back = PickCentre(cube, Looking({0, 400, 0}));
  ASSERT_TRUE(front.hit && back.hit);
  EXPECT_NEAR(back.position_lps.y, 20.0f, kHalfVoxel);
  EXPECT_NEAR(DistanceMm(front.position_lps, back.position_lps), 40.0f, kHalfVoxel);
}

TEST(Pick, AnswersTheLabelThereAndNothingWhereTheLabelIsHidden) {
  const auto cube = CubePhantom();
  const auto labels = CubeLabels(*cube);
  RenderSetup setup = Looking({0, -400, 0});
  const PickResult shown = PickCentre(cube, setup, labels);
  ASSERT_TRUE(shown.hit);
  ASSERT_TRUE(shown.label);
  EXPECT_EQ(shown.label->value, 1);
  EXPECT_EQ(shown.label->name, "cube");

  setup.labels.styles[1].visible = false;
  EXPECT_FALSE(PickCentre(cube, setup, labels).hit) << "the cube and its shell are hidden: nothing else is there";
}

// The path tracer's first collisions along a ray fall before depth t with
// probability 1 - exp(-tau(t)): their median is where the accumulated opacity
// reaches 0.5. A soft cube (0.5 per mm: the median 1.39 mm inside its face)
// seen face on, every pixel's first collisions over many frames.
TEST(Pick, StopsAtTheMedianOfThePathTracersFirstCollisions) {
  const auto cube = CubePhantom();
  const RenderSetup setup = Looking({0, -400, 0}, Surface(0.5f));
  CpuRenderer renderer;
  renderer.SetVolume(cube);
  renderer.SetTransferFunction(setup.transfer_function);
  FrameRequest request;
  request.camera = LookAt({0, -400, 0}, {0, 0, 0}, {0, 0, 1}, 2.0f, 16, 16);  // 14 mm across: all on the face
  request.max_bounces = 0;
  std::vector<float> depths;
  for (int frame = 0; frame < 50; ++frame) {
    request.frame = std::uint32_t(frame);
    renderer.Render(request);
    for (const Vec4f& hit : renderer.FirstHits()) {
      if (hit.w > 0) depths.push_back(hit.y);
    }
  }
  ASSERT_GT(depths.size(), 10000u) << "a path through the cube almost surely collides";
  std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
  const float median = depths[depths.size() / 2];
  const PickResult r = PickCentre(cube, setup);
  ASSERT_TRUE(r.hit);
  EXPECT_NEAR(r.position.y, median, 0.1f) << "the pick and the path tracer disagree on where opacity reaches 0.5";
  EXPECT_NEAR(r.position.y, -20.0f + std::log(2.0f) / 0.5f, 0.15f) << "ln 2 / sigma_t behind the face";
}

TEST(Pick, ARayThatMissesTheVolumeHitsNothing) {
  const auto cube = CubePhantom();
  const Picker picker(cube, nullptr, Looking({0, -400, 0}));
  EXPECT_FALSE(picker.PickPixel(0, 0).hit) << "the corner pixel looks past the 64 mm volume";
  EXPECT_FALSE(picker.PickRay({{0, -400, 0}, {0, -1, 0}}).hit) << "looking away";
}

TEST(Pick, AnEyeFarAwayFindsTheSameFace) {
  const Picker picker(CubePhantom(), nullptr, Looking({0, -400, 0}));
  const PickResult r = picker.PickRay({{0, -1e7f, 0}, {0, 1, 0}});
  ASSERT_TRUE(r.hit);
  EXPECT_NEAR(r.position.y, -20.0f, 2.0f) << "within float's precision at 1e7 mm (1 mm)";
}

TEST(Pick, APixelOrThresholdOutOfRangeIsRefused) {
  const Picker picker(CubePhantom(), nullptr, Looking({0, -400, 0}));
  EXPECT_THROW(picker.PickPixel(kViewport, 0), InputError);
  EXPECT_THROW(picker.PickPixel(0, -1), InputError);
  PickSettings zero;
  zero.threshold = 0.0f;
  EXPECT_THROW(picker.PickPixel(kCentre, kCentre, zero), InputError);
}

// A hollow cube: walls 2 mm thick (18 to 20 mm from the centre) of value 1000.
std::shared_ptr<const Volume> HollowCube() {
  const int n = 64;
  std::vector<float> values(std::size_t(n) * n * n, 0.0f);
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        const Vec3f c = Vec3f{float(x), float(y), float(z)} + Vec3f{0.5f - 32, 0.5f - 32, 0.5f - 32};
        const float d = MaxComponent(Abs(c));
        if (d >= 18.0f && d <= 20.0f) values[(std::size_t(z) * n + y) * n + x] = 1000.0f;
      }
  return std::make_shared<const Volume>(Vec3i{n, n, n}, Vec3f{1, 1, 1}, std::move(values), VolumeMetadata{});
}

TEST(Pick, OpacityAccumulatesThroughAThinShellToItsFarSide) {
  // Each wall holds an optical depth of 0.5 (2 mm at 0.25 per mm): 39% opaque,
  // two walls 63%. The ray reaches 50% in the far wall, 0.77 mm into it.
  const auto shell = HollowCube();
  const PickResult r = PickCentre(shell, Looking({0, -400, 0}, Surface(0.25f)));
  ASSERT_TRUE(r.hit);
  EXPECT_NEAR(r.position.y, 18.77f, kHalfVoxel) << "in the far wall";
  const PickResult near = PickCentre(shell, Looking({0, -400, 0}, Surface(0.25f)), nullptr, 0.3f);
  ASSERT_TRUE(near.hit);
  EXPECT_LT(near.position.y, -18.0f) << "30% is reached in the near wall";
}

TEST(Pick, AThresholdOfOneIsNeverReached) {
  // The renderer clamps extinction (32 per voxel): even an opaque cube lets
  // some light through, so full opacity is never reached. No hit.
  EXPECT_FALSE(PickCentre(CubePhantom(), Looking({0, -400, 0}), nullptr, 1.0f).hit);
  EXPECT_FALSE(PickCentre(HollowCube(), Looking({0, -400, 0}, Surface(0.25f)), nullptr, 1.0f).hit);
}

// A crop box keeping y from -10 mm on (LPS: posterior), cutting the cube's front.
v1::Clipping CropFront(bool cap) {
  v1::Clipping clipping;
  v1::CropBox& box = *clipping.mutable_crop_box();
  box.mutable_center()->set_y(40.0f);
  box.mutable_size()->set_x(200.0f);
  box.mutable_size()->set_y(100.0f);
  box.mutable_size()->set_z(200.0f);
  box.set_cap(cap);
  return clipping;
}

TEST(Pick, ACropBoxThatRemovesTheFrontFaceLandsDeeper) {
  const auto cube = CubePhantom();
  for (bool cap : {false, true}) {
    RenderSetup setup = Looking({0, -400, 0});
    setup.clip = ResolveClipping(CropFront(cap), *cube);
    const PickResult r = PickCentre(cube, setup);
    ASSERT_TRUE(r.hit) << "cap " << cap;
    EXPECT_NEAR(r.position_lps.y, -10.0f, kHalfVoxel) << "the cut face, cap " << cap;
  }
}

TEST(Pick, ACappedFaceStopsTheRayWhereItsOpacityReachesTheThreshold) {
  const auto cube = CubePhantom();
  RenderSetup setup = Looking({0, -400, 0});
  setup.clip = ResolveClipping(CropFront(true), *cube);
  const PickResult r = PickCentre(cube, setup);
  ASSERT_TRUE(r.hit);
  EXPECT_NEAR(r.position_lps.y, -10.0f, 1e-3f) << "on the cap itself: the tissue's opacity there is 1";
}

TEST(Pick, TricubicReconstructionFindsTheSameFace) {
  const auto cube = CubePhantom();
  RenderSetup setup = Looking({0, -400, 0});
  setup.reconstruction = Reconstruction::kTricubic;
  const PickResult r = PickCentre(cube, setup);
  ASSERT_TRUE(r.hit);
  EXPECT_NEAR(r.position_lps.y, -20.0f, kHalfVoxel);
}

// The volume's value at world point p, trilinear between voxel centres (clamped at the edges).
float TrilinearValue(const Volume& v, Vec3f p) {
  const Vec3f q = (p + v.extent_mm() * 0.5f) / v.spacing_mm() - Vec3f{0.5f, 0.5f, 0.5f};
  const Vec3f f{std::floor(q.x), std::floor(q.y), std::floor(q.z)};
  const Vec3f t = q - f;
  auto at = [&](int dx, int dy, int dz) {
    auto clamp = [](int i, int n) { return std::clamp(i, 0, n - 1); };
    return v.Value(clamp(int(f.x) + dx, v.dims().x), clamp(int(f.y) + dy, v.dims().y),
                   clamp(int(f.z) + dz, v.dims().z));
  };
  float sum = 0.0f;
  for (int k = 0; k < 8; ++k) {
    const int dx = k & 1, dy = k >> 1 & 1, dz = k >> 2 & 1;
    sum += (dx ? t.x : 1 - t.x) * (dy ? t.y : 1 - t.y) * (dz ? t.z : 1 - t.z) * at(dx, dy, dz);
  }
  return sum;
}

TEST(Pick, OnARealCtTheValueIsTheVoxelsThere) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const auto ct = std::make_shared<const Volume>(
      LoadVolume(ParseVolumeSpec((SharedData() / "ct-head-headsq/quarter.nhdr").string())));
  v1::Scene scene = MakePresetScene(DefaultPreset(*ct), *ct);
  scene.mutable_render()->set_width(64);
  scene.mutable_render()->set_height(64);
  ApplyDefaults(scene);
  const Picker picker(ct, nullptr, ResolveScene(scene, *ct));
  int hits = 0;
  for (int y = 8; y < 64; y += 8) {
    for (int x = 8; x < 64; x += 8) {
      const PickResult r = picker.PickPixel(x, y);
      if (!r.hit) continue;
      ++hits;
      const float expected = TrilinearValue(*ct, r.position);
      EXPECT_NEAR(r.value, expected, 1e-3f * std::max(1.0f, std::abs(expected))) << "pixel " << x << ", " << y;
    }
  }
  EXPECT_GT(hits, 10) << "the default preset shows the head over much of the view";
}

TEST(Measurements, DistanceAndAngleBetweenPoints) {
  EXPECT_FLOAT_EQ(DistanceMm({0, 0, 0}, {3, 4, 12}), 13.0f);
  EXPECT_NEAR(AngleDeg({1, 0, 0}, {0, 0, 0}, {0, 2, 0}), 90.0f, 1e-4f);
  EXPECT_NEAR(AngleDeg({1, 0, 0}, {0, 0, 0}, {1, 1, 0}), 45.0f, 1e-4f);
  EXPECT_NEAR(AngleDeg({1, 0, 0}, {0, 0, 0}, {-1, 1e-4f, 0}), 180.0f, 1e-2f);
  EXPECT_NEAR(AngleDeg({11, 5, 5}, {10, 5, 5}, {11, 5, 5}), 0.0f, 1e-4f);
  EXPECT_EQ(AngleDeg({10, 5, 5}, {10, 5, 5}, {11, 5, 5}), 0.0f) << "no direction from the vertex to itself";
}

// `cinevol pick` on a scene file of the cube phantom, as scripts run it.
TEST(Pick, TheCommandPrintsTheHitAsJson) {
  ScratchDir scratch;
  std::ofstream(scratch / "cube.json") << R"({
    "volume": {"phantom": {"kind": "CUBE", "size": 64, "spacing": 1, "value": 1000, "background": 0, "radius": 20}},
    "transferFunction": {"points": [{"value": 400, "opacity": 0}, {"value": 600, "opacity": 1}], "densityScale": 50},
    "camera": {"eye": {"y": -400}, "target": {}, "up": {"z": 1}, "fovYDeg": 20},
    "render": {"width": 65, "height": 65}})";
  auto pick = [&](const std::vector<std::string>& more) {
    std::vector<std::string> args{"pick", "--scene", (scratch / "cube.json").string()};
    args.insert(args.end(), more.begin(), more.end());
    return RunProgram(CliPath(), args, scratch / "pick.log");
  };
  auto [code, output] = pick({"--x", "32", "--y", "32", "--json"});
  ASSERT_EQ(code, 0) << output;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(output, m, std::regex(R"re("position":\[([^,\]]+),([^,\]]+),([^,\]]+)\])re")))
      << output;
  EXPECT_NEAR(std::stod(m[2].str()), -20.0, kHalfVoxel) << output;
  EXPECT_NE(output.find(R"("hit":true)"), std::string::npos) << output;
  EXPECT_NE(output.find(R"("pixel":[32,32])"), std::string::npos) << output;
  EXPECT_NE(output.find(R"("label":null)"), std::string::npos) << output;

  std::tie(code, output) = pick({"--x", "0", "--y", "0", "--json"});
  ASSERT_EQ(code, 0) << output;
  EXPECT_NE(output.find(R"("hit":false)"), std::string::npos) << output;

  std::tie(code, output) = pick({"--x", "32", "--y", "32", "--threshold", "0.9"});
  ASSERT_EQ(code, 0) << output;
  EXPECT_TRUE(
      std::regex_search(output, std::regex(R"(pixel \(32, 32\): LPS \(-?0\.00, -(19\.9|20\.0)\d, -?0\.00\) mm)")))
      << output;

  std::tie(code, output) = pick({"--x", "65", "--y", "0"});
  EXPECT_EQ(code, 2) << "a pixel outside the viewport is bad input: " << output;
  EXPECT_NE(output.find("outside the 65x65 viewport"), std::string::npos) << output;
}

}  // namespace
}  // namespace cinevol::testing

// What a user sees without touching a knob: the key light lights the volume
// without being in the picture, the default camera frames what the preset
// shows, and every shared data set's default preset shows structure.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "core/tone_map.h"
#include "encode/image_codecs.h"
#include "io/phantom.h"
#include "scene/presets.h"
#include "scene/scene_builder.h"
#include "scene/scene_file.h"
#include "scene/volume_kind.h"
#include "io/volume_loader.h"
#include "render/renderer.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

struct Rendered {
  ImageRgbF radiance;
  std::vector<Vec4f> first_hits;  // w = 1 where a camera ray met the volume
};

Rendered Render(const Volume& volume, v1::Scene scene, int width, int height, int spp) {
  scene.mutable_render()->set_width(width);
  scene.mutable_render()->set_height(height);
  scene.mutable_render()->set_spp(spp);
  ApplyDefaults(scene);
  const RenderSetup setup = ResolveScene(scene, volume);
  auto renderer = CreateRenderer(Backend::kCpu);
  renderer->SetVolume(std::make_shared<const Volume>(volume));
  renderer->SetTransferFunction(setup.transfer_function);
  renderer->SetLights(setup.lights);
  FrameRequest request;
  request.camera = setup.camera;
  request.spp = spp;
  request.max_bounces = setup.max_bounces;
  renderer->Render(request);
  return {renderer->Radiance(), renderer->FirstHits()};
}

Volume Phantom(v1::Phantom::Kind kind, int size) {
  v1::Phantom p;
  p.set_kind(kind);
  p.set_size(size);
  return MakePhantom(p);
}

// The silhouette's bounding box, as fractions of the viewport's shorter side.
struct Silhouette {
  float width = 0, height = 0;
  float Extent() const { return std::max(width, height); }
};

Silhouette SilhouetteOf(const Rendered& r) {
  const int w = r.radiance.width, h = r.radiance.height;
  int x0 = w, x1 = -1, y0 = h, y1 = -1;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (r.first_hits[y * w + x].w <= 0) continue;
      x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
    }
  }
  if (x1 < 0) return {};
  const float shorter = float(std::min(w, h));
  return {float(x1 - x0 + 1) / shorter, float(y1 - y0 + 1) / shorter};
}

// Coefficient of variation of the luminance over the silhouette: near 0 for
// a uniform block, larger for anything with structure.
double VariationInside(const Rendered& r) {
  double sum = 0, sum2 = 0, n = 0;
  for (std::size_t i = 0; i < r.radiance.pixels.size(); ++i) {
    if (r.first_hits[i].w <= 0) continue;
    const double l = Luminance(r.radiance.pixels[i]);
    sum += l, sum2 += l * l, ++n;
  }
  if (n < 2) return 0;
  const double mean = sum / n;
  return mean > 0 ? std::sqrt(std::max(0.0, sum2 / n - mean * mean)) / mean : 0;
}

TEST(OutOfTheBox, AnAreaLightInViewIsNotInThePictureUnlessVisible) {
  const Volume volume = Phantom(v1::Phantom::SPHERE, 32);
  v1::Scene scene = MakePresetScene("ct-bone", volume);
  // Put the key light behind the ball, facing the camera, larger than the
  // ball: around the silhouette the camera looks straight at it.
  const float r = Length(volume.extent_mm());
  v1::AreaLight* key = scene.mutable_lights(0)->mutable_area();
  key->mutable_center()->set_x(0), key->mutable_center()->set_y(r), key->mutable_center()->set_z(0);
  key->mutable_edge_u()->set_x(r), key->mutable_edge_u()->set_y(0), key->mutable_edge_u()->set_z(0);
  key->mutable_edge_v()->set_x(0), key->mutable_edge_v()->set_y(0), key->mutable_edge_v()->set_z(r);
  key->set_intensity(8);  // radiance 8: saturated where seen
  const Rendered hidden = Render(volume, scene, 48, 48, 4);
  key->set_visible(true);
  const Rendered shown = Render(volume, scene, 48, 48, 4);

  auto saturated = [](const Rendered& img) {
    int n = 0;
    for (const Vec3f& p : img.radiance.pixels) n += Luminance(p) > 4.0f;
    return n;
  };
  EXPECT_EQ(saturated(hidden), 0) << "the lamp is in the picture by default";
  EXPECT_GT(saturated(shown), 48 * 48 / 10) << "a visible lamp should fill the view around the ball";
  // The light on the volume is the same: pixels well inside the ball took
  // the same samples and got the same light (at its edge, the pixel filter
  // reaches 1.5 pixels out, to where the lamp is seen).
  int compared = 0;
  for (int y = 2; y < 46; ++y) {
    for (int x = 2; x < 46; ++x) {
      bool inside = true;
      for (int dy = -2; dy <= 2; ++dy) {
        for (int dx = -2; dx <= 2; ++dx) inside &= hidden.first_hits[(y + dy) * 48 + x + dx].w > 0;
      }
      if (!inside) continue;
      ++compared;
      const int i = y * 48 + x;
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(hidden.radiance.pixels[i][c], shown.radiance.pixels[i][c], 1e-5f);
    }
  }
  EXPECT_GT(compared, 50);
}

TEST(OutOfTheBox, ThePresetLightGivesEveryVolumeSizeTheSameLight) {
  // The same ball at two scales, in the same framing: the same image.
  auto render = [](float spacing) {
    v1::Phantom p;
    p.set_kind(v1::Phantom::SPHERE);
    p.set_size(24);
    p.set_spacing(spacing);
    const Volume volume = MakePhantom(p);
    return Render(volume, MakePresetScene("ct-bone", volume), 32, 32, 16);
  };
  const Rendered small = render(0.25f), large = render(4.0f);
  double mean_small = 0, mean_large = 0;
  for (std::size_t i = 0; i < small.radiance.pixels.size(); ++i) {
    mean_small += Luminance(small.radiance.pixels[i]);
    mean_large += Luminance(large.radiance.pixels[i]);
  }
  EXPECT_GT(mean_small, 0);
  // Extinction is per mm, so the small ball is thinner; the surface the
  // bone preset shows is opaque at both scales.
  EXPECT_NEAR(mean_small / mean_large, 1.0, 0.15);
}

TEST(OutOfTheBox, NamedViewsFillFourFifthsOfTheShorterSide) {
  const Volume volume = Phantom(v1::Phantom::CUBE, 32);
  v1::Scene scene = MakePresetScene("ct-bone", volume);
  for (auto [width, height] : {std::pair{64, 64}, {96, 48}, {48, 96}}) {
    const Silhouette s = SilhouetteOf(Render(volume, scene, width, height, 1));
    EXPECT_NEAR(s.Extent(), 0.8f, 0.06f) << width << "x" << height;
  }
}

TEST(OutOfTheBox, AThinSlabOfAxialSlicesIsSeenFromTheFeet) {
  VolumeMetadata meta;
  meta.source = "slab";
  const Volume slab({32, 32, 4}, {1, 1, 1}, std::vector<float>(32 * 32 * 4, 1000.0f), meta);
  EXPECT_EQ(MakePresetScene("ct-bone", slab).camera().view(), v1::INFERIOR);  // as PACS shows axial images
  const Volume cube({32, 32, 32}, {1, 1, 1}, std::vector<float>(32 * 32 * 32, 1000.0f), meta);
  EXPECT_EQ(MakePresetScene("ct-bone", cube).camera().view(), v1::ANTERIOR);
}

// PACS shows an axial image from the feet: anterior up, the patient's left on
// the right. A slab framed by a ring of bone, with a block of bone filling its
// anterior-left quarter: the block must show in the picture's top right.
TEST(OutOfTheBox, ASlabShowsThePatientsLeftOnTheRightAndAnteriorUp) {
  const Vec3i dims{32, 32, 4};
  std::vector<float> values(std::size_t(dims.x) * dims.y * dims.z, -1000.0f);
  for (int z = 0; z < dims.z; ++z) {
    for (int y = 0; y < dims.y; ++y) {
      for (int x = 0; x < dims.x; ++x) {
        const bool ring = x == 0 || y == 0 || x == dims.x - 1 || y == dims.y - 1;
        const bool anterior_left = y < 16 && x >= 16;  // LPS: low y is anterior, high x the patient's left
        if (ring || anterior_left) values[(std::size_t(z) * dims.y + y) * dims.x + x] = 1500.0f;
      }
    }
  }
  VolumeMetadata meta;
  meta.source = "slab";
  meta.modality = "CT";
  meta.value_unit = "HU";
  const Volume slab(dims, {1, 1, 1}, values, meta);
  const Rendered r = Render(slab, MakePresetScene("ct-bone", slab), 64, 64, 1);
  int quadrant[2][2] = {};  // [top?][right?]
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) {
      if (r.first_hits[std::size_t(y) * 64 + x].w > 0) ++quadrant[y < 32][x >= 32];
    }
  }
  const int elsewhere = std::max({quadrant[0][0], quadrant[0][1], quadrant[1][0]});
  EXPECT_GT(quadrant[1][1], 3 * elsewhere) << "the filled quarter is not at the top right: the view is mirrored or "
                                              "upside down";
}

struct DataSet {
  const char* path;  // under ../shared/data, or a phantom spec
  v1::VolumeKind kind;
};

void PrintTo(const DataSet& d, std::ostream* os) { *os << d.path; }

class DefaultPreset : public ::testing::TestWithParam<DataSet> {};

TEST_P(DefaultPreset, ShowsStructureAndFillsTheView) {
  const DataSet& d = GetParam();
  const bool phantom = std::string_view(d.path).starts_with("phantom:");
  if (!phantom) CINEVOL_REQUIRE_SHARED_DATA();
  const Volume volume = LoadVolume(ParseVolumeSpec(phantom ? d.path : (SharedData() / d.path).string()));
  const VolumeKindJudgement kind = JudgeVolumeKind(volume);
  EXPECT_EQ(kind.kind, d.kind) << kind.reason;
  v1::Scene scene = MakePresetScene(cinevol::DefaultPreset(volume), volume);
  scene.clear_transfer_function();  // neither points nor a preset: the volume's default
  const Rendered r = Render(volume, scene, 64, 64, 4);
  const Silhouette s = SilhouetteOf(r);
  EXPECT_GE(s.Extent(), 0.7f) << s.width << " x " << s.height;
  // CINEVOL_TEST_IMAGES=DIR keeps what the test saw, for people to look at.
  if (const char* dir = std::getenv("CINEVOL_TEST_IMAGES")) {
    const std::string name = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    WriteFile(std::filesystem::path(dir) / (name.substr(name.find('/') + 1) + ".png"),
              EncodePng(ToneMap(r.radiance, 0)));
  }
  EXPECT_LE(s.Extent(), 0.9f) << s.width << " x " << s.height;
  EXPECT_GT(VariationInside(r), 0.2) << "a uniform block";
}

INSTANTIATE_TEST_SUITE_P(
    SharedData, DefaultPreset,
    ::testing::Values(DataSet{"phantom:head?size=64", v1::CT_HU},
                      DataSet{"ct-body-totalsegmentator/aorta_ct_cropped.nii.gz", v1::CT_HU},
                      DataSet{"ct-body-totalsegmentator/pulmonary_ct_cropped.nii.gz", v1::CT_HU},
                      DataSet{"ct-body-totalsegmentator/example_ct_sm.nii.gz", v1::CT_HU},
                      DataSet{"ct-body-totalsegmentator/example_ct_dicom", v1::CT_HU},
                      DataSet{"ct-chest-lidc2/LIDC2.nhdr", v1::OTHER},
                      DataSet{"ct-head-avm/CT_AVM.nii.gz", v1::OTHER},
                      DataSet{"ct-head-cthead/DERIVED_CThead.nhdr", v1::CT_SCALED},
                      DataSet{"ct-head-headsq/quarter.nhdr", v1::CT_SCALED},
                      DataSet{"ct-objects-openscivis/bonsai.nii.gz", v1::OTHER},
                      DataSet{"ct-objects-openscivis/engine.nii.gz", v1::OTHER},
                      DataSet{"mr-chest-dicom-seg3d", v1::MR},
                      DataSet{"mr-head-seg3d-nifti/MR.nii.gz", v1::OTHER}),
    [](const auto& info) {
      std::string name = std::filesystem::path(info.param.path).stem().string();
      for (char& c : name) c = std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
      return name;
    });

}  // namespace
}  // namespace cinevol::testing

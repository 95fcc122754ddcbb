// Presets on real studies (issue 32): where each preset's first collisions
// (the renderer's first-hit buffer, kept for the denoiser) land. Lung for
// the lung preset, contrast lumen for angiography, bone for bone, the head
// and not its localizer frame for MR, the skeleton for micro-CT; ground
// truth from TotalSegmentator's labels, from a reference segmentation of the
// contrast crops made with what no transfer function sees (connectivity and
// neighbourhoods), or from phantoms built with their tissues known. Small
// CPU frames at one sample per pixel: a pixel's first hit is then one
// path's, an unbiased draw of where the preset stops a camera ray.
#include <gtest/gtest.h>

#include <cmath>
#include <fmt/format.h>
#include <functional>
#include <map>
#include <random>
#include <tuple>

#include "core/transfer_function.h"
#include "io/label_volume.h"
#include "scene/presets.h"
#include "scene/scene_builder.h"
#include "scene/scene_file.h"
#include "scene/volume_kind.h"
#include "io/volume_loader.h"
#include "pipeline/frame_pipeline.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

// A tissue per voxel, as the test's ground truth.
enum Tissue : std::uint8_t { kNone = 0, kLung, kLumen, kBone, kHead, kFrame, kSkeleton, kBody, kJet };

struct TruthVolume {
  std::shared_ptr<const Volume> image;
  std::vector<std::uint8_t> tissue;  // per voxel, x fastest

  Vec3i Voxel(Vec3f world) const {
    const Vec3f q = (world + image->extent_mm() * 0.5f) / image->spacing_mm() - Vec3f{0.5f, 0.5f, 0.5f};
    const Vec3i d = image->dims();
    return {std::clamp(int(std::lround(q.x)), 0, d.x - 1), std::clamp(int(std::lround(q.y)), 0, d.y - 1),
            std::clamp(int(std::lround(q.z)), 0, d.z - 1)};
  }
  std::size_t Index(Vec3i v) const { return (std::size_t(v.z) * image->dims().y + v.y) * image->dims().x + v.x; }
  // The tissue of the nearest voxel, or of a voxel beside it: segmentations
  // stop short of a structure's partial-volume rim, where the first hit on a
  // surface lies.
  bool Near(Vec3f world, Tissue t) const {
    const Vec3i c = Voxel(world), d = image->dims();
    for (int z = std::max(0, c.z - 1); z <= std::min(d.z - 1, c.z + 1); ++z) {
      for (int y = std::max(0, c.y - 1); y <= std::min(d.y - 1, c.y + 1); ++y) {
        for (int x = std::max(0, c.x - 1); x <= std::min(d.x - 1, c.x + 1); ++x) {
          if (tissue[Index({x, y, z})] == t) return true;
        }
      }
    }
    return false;
  }
};

// One frame of `scene` (a preset scene) at size x size, one sample a pixel.
struct Frame {
  std::vector<Vec4f> first_hits;  // w = 1 where the path met tissue
  Camera camera;
};

Frame Render(const std::shared_ptr<const Volume>& volume, v1::Scene scene, int size) {
  scene.mutable_render()->set_width(size);
  scene.mutable_render()->set_height(size);
  scene.mutable_render()->set_spp(1);
  ApplyDefaults(scene);
  FramePipeline pipeline(Backend::kCpu, volume);
  FrameSettings settings;
  settings.denoiser.method = DenoiseMethod::kNone;
  pipeline.Update(scene, settings);
  pipeline.RenderFrame();
  return {pipeline.FirstHits(), ResolveScene(scene, *volume).camera};
}

v1::Scene PresetScene(const Volume& volume, const std::string& preset) { return MakePresetScene(preset, volume); }

// The fraction of hits in tissue `t`, among pixels `counted` keeps (all by
// default); pixels without a hit count as missing it.
struct Share {
  int in = 0, of = 0;
  double Fraction() const { return of ? double(in) / of : 0; }
};

Share ShareIn(const Frame& f, const TruthVolume& truth, Tissue t, const std::function<bool(int)>& counted = {},
              bool misses_count = false) {
  Share s;
  for (int i = 0; i < int(f.first_hits.size()); ++i) {
    if (counted && !counted(i)) continue;
    const Vec4f h = f.first_hits[std::size_t(i)];
    if (h.w == 0 && !misses_count) continue;
    ++s.of;
    s.in += h.w != 0 && truth.Near(Xyz(h), t);
  }
  return s;
}

// Pixels whose central ray crosses at least `min_voxels` voxels of tissue t.
std::vector<bool> RaysCrossing(const Frame& f, const TruthVolume& truth, Tissue t, int min_voxels) {
  const Camera& c = f.camera;
  const float step = 0.5f * MinComponent(truth.image->spacing_mm());
  const Vec3f half = truth.image->extent_mm() * 0.5f;
  std::vector<bool> crossing(std::size_t(c.width) * c.height, false);
  for (int y = 0; y < c.height; ++y) {
    for (int x = 0; x < c.width; ++x) {
      const Ray r = c.GenerateRay(float(x) + 0.5f, float(y) + 0.5f, 0.5f, 0.5f);
      const float far = Length(r.origin) + Length(half) * 2.0f;
      int seen = 0;
      std::size_t last = SIZE_MAX;
      for (float s = 0; s < far && seen < min_voxels; s += step) {
        const Vec3f p = r.origin + r.direction * s;
        if (std::abs(p.x) > half.x || std::abs(p.y) > half.y || std::abs(p.z) > half.z) continue;
        const std::size_t i = truth.Index(truth.Voxel(p));
        if (i != last && truth.tissue[i] == t) ++seen;
        last = i;
      }
      crossing[std::size_t(y) * c.width + x] = seen >= min_voxels;
    }
  }
  return crossing;
}

std::string Describe(const char* what, Share s) {
  return fmt::format("{}: {} of {} ({:.1f}%)", what, s.in, s.of, 100.0 * s.Fraction());
}

// --- TotalSegmentator's abdomen CT with its 117 labels -----------------------

bool IsBoneLabel(int l) { return (l >= 25 && l <= 50) || (l >= 69 && l <= 78) || (l >= 91 && l <= 117); }
bool IsLungLabel(int l) { return (l >= 10 && l <= 14) || l == 16; }

TruthVolume LabelledAbdomen() {
  const auto folder = SharedData() / "ct-body-totalsegmentator";
  TruthVolume t;
  t.image = std::make_shared<const Volume>(LoadVolumeFile(folder / "example_ct_sm.nii.gz"));
  const LabelVolume labels = LoadLabelVolume(folder / "example_seg.nii.gz", *t.image);
  t.tissue.resize(labels.labels.size());
  for (std::size_t i = 0; i < labels.labels.size(); ++i) {
    const int l = labels.labels[i];
    t.tissue[i] = IsLungLabel(l) ? kLung : IsBoneLabel(l) ? kBone : l ? kBody : kNone;
  }
  return t;
}

// The lung preset shows the lungs through a translucent body: where a camera
// ray crosses lung, its first collision is in the lung, not on the skin. The
// abdomen holds only the lung bases, a few voxels thick, behind the skin and
// in front of bowel gas (which the preset shows too: it shows every boundary
// of air), so the share is modest there; the heart crop below has whole lungs.
TEST(PresetTissue, TheLungPresetStopsRaysInTheLungBasesNotOnTheBody) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const TruthVolume truth = LabelledAbdomen();
  const Frame f = Render(truth.image, PresetScene(*truth.image, "ct-lung"), 96);
  const std::vector<bool> crossing = RaysCrossing(f, truth, kLung, 3);
  const Share lung = ShareIn(f, truth, kLung, [&](int i) { return crossing[std::size_t(i)]; }, true);
  std::printf("%s\n", Describe("rays crossing lung that stop in it", lung).c_str());
  ASSERT_GT(lung.of, 150) << "rays through the lung bases";
  EXPECT_GE(lung.Fraction(), 0.3) << Describe("rays crossing lung that stop in it", lung);
}

// The pulmonary crop's lungs: 6-connected pieces of at least 20000 voxels
// at -500 HU or less (aerated lung; its vessels and bronchial walls lie
// within the one-voxel tolerance of Near).
TruthVolume LungsOfTheHeartCrop() {
  TruthVolume t;
  t.image = std::make_shared<const Volume>(
      LoadVolumeFile(SharedData() / "ct-body-totalsegmentator" / "pulmonary_ct_cropped.nii.gz"));
  const Volume& v = *t.image;
  const Vec3i d = v.dims();
  t.tissue.assign(v.voxel_count(), kNone);
  std::vector<bool> seen(v.voxel_count(), false);
  for (std::size_t s = 0; s < v.voxel_count(); ++s) {
    if (seen[s] || v.ValueAtIndex(s) > -500.0f) continue;
    std::vector<std::size_t> piece{s}, stack{s};
    seen[s] = true;
    while (!stack.empty()) {
      const std::size_t i = stack.back();
      stack.pop_back();
      const int x = int(i % d.x), y = int(i / d.x % d.y), z = int(i / (std::size_t(d.x) * d.y));
      const int nb[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
      for (const auto& o : nb) {
        const int a = x + o[0], b = y + o[1], c = z + o[2];
        if (a < 0 || b < 0 || c < 0 || a >= d.x || b >= d.y || c >= d.z) continue;
        const std::size_t j = (std::size_t(c) * d.y + b) * d.x + a;
        if (seen[j] || v.ValueAtIndex(j) > -500.0f) continue;
        seen[j] = true;
        piece.push_back(j);
        stack.push_back(j);
      }
    }
    if (piece.size() >= 20000) {
      for (std::size_t i : piece) t.tissue[i] = kLung;
    }
  }
  return t;
}

TEST(PresetTissue, TheLungPresetStopsRaysInTheLungsOfAChestCrop) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const TruthVolume truth = LungsOfTheHeartCrop();
  const Frame f = Render(truth.image, PresetScene(*truth.image, "ct-lung"), 64);
  const std::vector<bool> crossing = RaysCrossing(f, truth, kLung, 3);
  const Share lung = ShareIn(f, truth, kLung, [&](int i) { return crossing[std::size_t(i)]; }, true);
  std::printf("%s\n", Describe("rays crossing lung that stop in it", lung).c_str());
  ASSERT_GT(lung.of, 1000);
  EXPECT_GE(lung.Fraction(), 0.7) << Describe("rays crossing lung that stop in it", lung);
}

// ct-bone, the CT default, on plain CT: its first collisions are bone.
TEST(PresetTissue, TheBonePresetStopsRaysOnBoneOfAPlainCt) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const TruthVolume truth = LabelledAbdomen();
  const Frame f = Render(truth.image, PresetScene(*truth.image, "ct-bone"), 64);
  const Share bone = ShareIn(f, truth, kBone);
  ASSERT_GT(bone.of, 200);
  std::printf("%s\n", Describe("first hits on bone (plain abdomen)", bone).c_str());
  EXPECT_GE(bone.Fraction(), 0.85) << Describe("first hits on bone", bone);
}

// --- The contrast crops, with a reference segmentation -----------------------

// Bone: 6-connected pieces of voxels at 700 HU or more whose densest voxel is
// below 2600 HU, with a voxel of rim around them; the pieces reaching 2600 HU
// are undiluted contrast flowing in through a vein (a jet; bone does not get
// there), which a bone preset cannot tell from bone by value. Lumen: pieces
// of at least 30 voxels with values on the blood pool (its peak - 150 to its
// edge + 150 HU), more than two voxels from bone. Lumen: pieces of at least 500
// voxels with values on the blood pool (its peak - 150 to its edge + 150 HU),
// more than two voxels from bone. No transfer function sees connectivity or
// neighbourhoods, so this is an independent reference (trabecular bone deep
// inside a vertebra may pass for lumen; few rays get there).
TruthVolume ContrastCrop(const char* file) {
  TruthVolume t;
  t.image = std::make_shared<const Volume>(LoadVolumeFile(SharedData() / "ct-body-totalsegmentator" / file));
  const Volume& v = *t.image;
  const BloodPool pool = FindBloodPool(v.histogram());
  const Vec3i d = v.dims();
  const std::size_t n = v.voxel_count();
  // Marks each 6-connected piece of voxels `in` keeps with the tissue
  // `kind` gives it (kNone: unmarked).
  auto pieces = [&](const std::function<bool(std::size_t)>& in,
                    const std::function<Tissue(const std::vector<std::size_t>&)>& kind,
                    std::vector<std::uint8_t>& out) {
    std::vector<bool> seen(n, false);
    for (std::size_t s = 0; s < n; ++s) {
      if (seen[s] || !in(s)) continue;
      std::vector<std::size_t> piece{s}, stack{s};
      seen[s] = true;
      while (!stack.empty()) {
        const std::size_t i = stack.back();
        stack.pop_back();
        const int x = int(i % d.x), y = int(i / d.x % d.y), z = int(i / (std::size_t(d.x) * d.y));
        const int nb[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
        for (const auto& o : nb) {
          const int a = x + o[0], b = y + o[1], c = z + o[2];
          if (a < 0 || b < 0 || c < 0 || a >= d.x || b >= d.y || c >= d.z) continue;
          const std::size_t j = (std::size_t(c) * d.y + b) * d.x + a;
          if (seen[j] || !in(j)) continue;
          seen[j] = true;
          piece.push_back(j);
          stack.push_back(j);
        }
      }
      if (const Tissue t = kind(piece); t != kNone) {
        for (std::size_t i : piece) out[i] = t;
      }
    }
  };
  auto dilate = [&](const std::vector<std::uint8_t>& src, std::uint8_t tissue, int r) {
    std::vector<bool> near(n, false);
    for (std::size_t i = 0; i < n; ++i) {
      if (src[i] != tissue) continue;
      const int x = int(i % d.x), y = int(i / d.x % d.y), z = int(i / (std::size_t(d.x) * d.y));
      for (int c = std::max(0, z - r); c <= std::min(d.z - 1, z + r); ++c)
        for (int b = std::max(0, y - r); b <= std::min(d.y - 1, y + r); ++b)
          for (int a = std::max(0, x - r); a <= std::min(d.x - 1, x + r); ++a)
            near[(std::size_t(c) * d.y + b) * d.x + a] = true;
    }
    return near;
  };
  std::vector<std::uint8_t> dense(n, kNone);
  pieces([&](std::size_t i) { return v.ValueAtIndex(i) >= 700.0f; },
         [&](const std::vector<std::size_t>& p) {
           float top = -INFINITY;
           for (std::size_t i : p) top = std::max(top, v.ValueAtIndex(i));
           return top < 2600.0f ? kBone : kJet;
         },
         dense);
  const std::vector<bool> bone_rim = dilate(dense, kBone, 1), near_bone = dilate(dense, kBone, 2);
  const std::vector<bool> jet_rim = dilate(dense, kJet, 1);
  t.tissue.assign(n, kNone);
  pieces([&](std::size_t i) {
           const float h = v.ValueAtIndex(i);
           return !near_bone[i] && h >= pool.peak - 150.0f && h <= pool.top + 150.0f;
         },
         [](const std::vector<std::size_t>& p) { return p.size() >= 30 ? kLumen : kNone; }, t.tissue);
  for (std::size_t i = 0; i < n; ++i) {
    if (bone_rim[i]) t.tissue[i] = kBone;
    if (jet_rim[i]) t.tissue[i] = kJet;
  }
  return t;
}

// Red is what the angiography preset gives contrast blood: the hits whose
// colour is red.
std::function<bool(int)> ShownRed(const Frame& f, const Volume& v, const TransferFunction& tf) {
  return [&f, &v, &tf](int i) {
    const Vec4f h = f.first_hits[std::size_t(i)];
    if (h.w == 0) return false;
    const Vec3f q = (Xyz(h) + v.extent_mm() * 0.5f) / v.spacing_mm() - Vec3f{0.5f, 0.5f, 0.5f};
    const Vec3i d = v.dims();
    const float value =
        v.Value(std::clamp(int(std::lround(q.x)), 0, d.x - 1), std::clamp(int(std::lround(q.y)), 0, d.y - 1),
                std::clamp(int(std::lround(q.z)), 0, d.z - 1));
    const Vec3f c = Evaluate(tf, value).diffuse;
    return c.x > 2.0f * c.y;
  };
}

class ContrastCrops : public ::testing::TestWithParam<const char*> {};

TEST_P(ContrastCrops, TheirBloodPoolIsFound) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const Volume v = LoadVolumeFile(SharedData() / "ct-body-totalsegmentator" / GetParam());
  const BloodPool pool = FindBloodPool(v.histogram());
  EXPECT_GT(pool.peak, 350.0f);
  EXPECT_LT(pool.peak, 600.0f);
  EXPECT_GT(pool.top, pool.peak + 50.0f);
  EXPECT_LT(pool.top, pool.peak + 300.0f);
}

// Angiography: red hits are lumen, and bone is not red.
TEST_P(ContrastCrops, TheAngiographyPresetShowsLumenRedAndBoneNot) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const TruthVolume truth = ContrastCrop(GetParam());
  const v1::Scene scene = PresetScene(*truth.image, "ct-vessels");
  const Frame f = Render(truth.image, scene, 64);
  const TransferFunction tf = ResolveTransferFunction(scene.transfer_function(), *truth.image);
  const auto red = ShownRed(f, *truth.image, tf);
  Share red_lumen;  // the jet is contrast lumen too
  for (int i = 0; i < int(f.first_hits.size()); ++i) {
    if (!red(i)) continue;
    const Vec3f h = Xyz(f.first_hits[std::size_t(i)]);
    ++red_lumen.of;
    red_lumen.in += truth.Near(h, kLumen) || truth.Near(h, kJet);
  }
  const Share bone_red = [&] {
    Share s;
    for (int i = 0; i < int(f.first_hits.size()); ++i) {
      const Vec4f h = f.first_hits[std::size_t(i)];
      if (h.w == 0 || !truth.Near(Xyz(h), kBone) || truth.Near(Xyz(h), kLumen)) continue;
      ++s.of;
      s.in += red(i);
    }
    return s;
  }();
  std::printf("%s\n%s\n", Describe("red hits in the lumen", red_lumen).c_str(),
              Describe("bone hits shown red", bone_red).c_str());
  ASSERT_GT(red_lumen.of, 300);
  // By value alone: most red is lumen, and half the bone is still red where
  // its rim or a thin bone crosses the blood pool's values.
  EXPECT_GE(red_lumen.Fraction(), 0.65) << Describe("red hits in the lumen", red_lumen);
  EXPECT_LE(bone_red.Fraction(), 0.6) << Describe("bone hits shown red", bone_red);
}

// ct-bone on a contrast CT: bone, not the blood pool.
TEST_P(ContrastCrops, TheBonePresetStopsRaysOnBoneNotInTheBloodPool) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const TruthVolume truth = ContrastCrop(GetParam());
  const Frame f = Render(truth.image, PresetScene(*truth.image, "ct-bone"), 64);
  const Share bone = ShareIn(f, truth, kBone), lumen = ShareIn(f, truth, kLumen), jet = ShareIn(f, truth, kJet);
  std::printf("%s\n%s\n%s\n", Describe("first hits on bone", bone).c_str(),
              Describe("first hits in the lumen", lumen).c_str(),
              Describe("first hits on the contrast jet", jet).c_str());
  ASSERT_GT(bone.of, 100);
  EXPECT_GE(bone.Fraction() + jet.Fraction(), 0.9) << Describe("first hits on bone", bone);
  EXPECT_LE(lumen.Fraction(), 0.1) << Describe("first hits in the lumen", lumen);
}

INSTANTIATE_TEST_SUITE_P(SharedData, ContrastCrops,
                         ::testing::Values("aorta_ct_cropped.nii.gz", "pulmonary_ct_cropped.nii.gz"),
                         [](const auto& info) {
                           return std::string(info.param).substr(0, info.param[0] == 'a' ? 5 : 9);
                         });

TEST(BloodPool, APlainCtHasNone) {
  CINEVOL_REQUIRE_SHARED_DATA();
  for (const char* file : {"example_ct_sm.nii.gz", "example_ct.nii.gz"}) {
    const Volume v = LoadVolumeFile(SharedData() / "ct-body-totalsegmentator" / file);
    EXPECT_EQ(FindBloodPool(v.histogram()).peak, 0.0f) << file;
  }
}

// A preset that does not fit the data says so: angiography on a CT without
// contrast, a CT preset in HU on MR, an MR preset on CT; a fitting one says nothing.
TEST(PresetMisfit, PresetsThatDoNotFitTheDataSaySo) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const Volume contrast = LoadVolumeFile(SharedData() / "ct-body-totalsegmentator" / "aorta_ct_cropped.nii.gz");
  const Volume plain = LoadVolumeFile(SharedData() / "ct-body-totalsegmentator" / "example_ct_sm.nii.gz");
  const Volume mr = LoadVolumeFile(SharedData() / "mr-head-seg3d-nifti" / "MR.nii.gz");
  EXPECT_EQ(PresetMisfit("ct-vessels", contrast), "");
  EXPECT_EQ(PresetMisfit("ct-bone", plain), "");
  EXPECT_EQ(PresetMisfit("mr-default", mr), "");
  const std::string no_pool = PresetMisfit("ct-vessels", plain);
  EXPECT_NE(no_pool.find("no blood-pool peak"), std::string::npos) << no_pool;
  const std::string hu_on_mr = PresetMisfit("ct-bone", mr);
  // The MR NIfTI names no modality: its kind is OTHER, whose default is 'auto'.
  EXPECT_NE(hu_on_mr.find("for CT in Hounsfield units, and this volume is OTHER"), std::string::npos) << hu_on_mr;
  EXPECT_NE(hu_on_mr.find("'auto' is this volume's default"), std::string::npos) << hu_on_mr;
  const std::string mr_on_ct = PresetMisfit("mr-t2-brain", plain);
  EXPECT_NE(mr_on_ct.find("is for MR"), std::string::npos) << mr_on_ct;
  EXPECT_EQ(PresetMisfit("no-such-preset", mr), "") << "an unknown preset is refused elsewhere, by name";
}

// --- Phantoms: an MR head in a localizer frame, a micro-CT of a mouse ---------

float Noise(std::mt19937& rng, float sigma) { return std::normal_distribution<float>(0.0f, sigma)(rng); }

// A box blur over 3 voxels along each axis: the partial volume of a scanner.
std::vector<float> Blurred(std::vector<float> v, Vec3i d) {
  for (int a = 0; a < 3; ++a) {
    std::vector<float> out(v.size());
    const std::size_t stride = a == 0 ? 1 : a == 1 ? std::size_t(d.x) : std::size_t(d.x) * d.y;
    for (std::size_t i = 0; i < v.size(); ++i) {
      const int c = a == 0 ? int(i % d.x) : a == 1 ? int(i / d.x % d.y) : int(i / (std::size_t(d.x) * d.y));
      const float lo = c > 0 ? v[i - stride] : v[i], hi = c < d[a] - 1 ? v[i + stride] : v[i];
      out[i] = (lo + v[i] + hi) / 3.0f;
    }
    v.swap(out);
  }
  return v;
}

struct Phantom {
  std::vector<float> values;
  std::vector<std::uint8_t> tissue;
};

// Values and tissue from a function of the voxel centre in mm (centred).
Phantom Build(Vec3i d, float spacing, const std::function<std::pair<float, Tissue>(Vec3f)>& f) {
  Phantom p;
  p.values.resize(std::size_t(d.x) * d.y * d.z);
  p.tissue.resize(p.values.size());
  std::size_t i = 0;
  for (int z = 0; z < d.z; ++z)
    for (int y = 0; y < d.y; ++y)
      for (int x = 0; x < d.x; ++x, ++i) {
        const Vec3f c = (Vec3f{float(x), float(y), float(z)} + Vec3f{0.5f, 0.5f, 0.5f} - ToFloat(d) * 0.5f) * spacing;
        std::tie(p.values[i], p.tissue[i]) = f(c);
      }
  return p;
}

float EllipsoidRadius(Vec3f p, Vec3f radii) { return Length(p / radii); }

// A T1 head with contrast (bright scalp fat and vessels) in a stereotactic
// frame: N-shaped fiducial rods, thin and brighter than anything, beside
// the head near the left, right and anterior faces of the volume (LPS:
// x left, y posterior, z superior).
TruthVolume MrHeadInAFrame() {
  const Vec3i d{128, 128, 128};
  const float mm = 1.5f;
  const float edge = 0.5f * d.x * mm - 8.0f;  // rods 8 mm inside the faces
  constexpr float kRod = 2.25f;                // fiducial tubes 4.5 mm across
  auto rod = [](Vec3f p, Vec3f a, Vec3f b) {   // distance to segment a..b
    const Vec3f ab = b - a;
    const float t = std::clamp(Dot(p - a, ab) / Dot(ab, ab), 0.0f, 1.0f);
    return Length(p - (a + ab * t));
  };
  const Phantom p = Build(d, mm, [&](Vec3f c) -> std::pair<float, Tissue> {
    const float r = EllipsoidRadius(c, {65, 72, 72});
    for (float side : {-1.0f, 1.0f}) {
      const float x = side * edge;
      if (std::min({rod(c, {x, -50, -60}, {x, -50, 60}), rod(c, {x, 50, -60}, {x, 50, 60}),
                    rod(c, {x, -50, -60}, {x, 50, 60})}) < kRod) {
        return {2500, kFrame};
      }
    }
    if (std::min({rod(c, {-50, -edge, -60}, {-50, -edge, 60}), rod(c, {50, -edge, -60}, {50, -edge, 60}),
                  rod(c, {-50, -edge, -60}, {50, -edge, 60})}) < kRod) {
      return {2500, kFrame};
    }
    if (r > 1.0f) return {0, kNone};
    if (r > 0.93f) return {700, kHead};  // scalp fat, bright in T1
    if (r > 0.88f) return {60, kHead};   // skull
    if (r > 0.84f) return {120, kHead};  // CSF
    return {std::abs(c.x) < 3 ? 120.0f : 420.0f, kHead};  // brain, the midline fissure
  });
  std::mt19937 rng(7);
  std::vector<float> values = Blurred(p.values, d);
  for (float& v : values) v = std::max(0.0f, v + Noise(rng, 10.0f));
  VolumeMetadata meta;
  meta.source = "phantom MR head in a frame";
  meta.modality = "MR";
  TruthVolume t;
  t.image = std::make_shared<const Volume>(d, Vec3f{mm, mm, mm}, std::move(values), meta);
  t.tissue = p.tissue;
  return t;
}

TEST(PresetTissue, TheMrDefaultSeesTheHeadNotTheLocalizerFrame) {
  const TruthVolume truth = MrHeadInAFrame();
  ASSERT_EQ(JudgeVolumeKind(*truth.image).kind, v1::MR);
  v1::Scene scene = PresetScene(*truth.image, DefaultPreset(*truth.image));
  ASSERT_TRUE(scene.clipping().has_crop_box()) << "the default scene should crop the frame away";
  const Frame f = Render(truth.image, scene, 64);
  const Share head = ShareIn(f, truth, kHead), frame = ShareIn(f, truth, kFrame);
  std::printf("%s\n%s\n", Describe("first hits on the head", head).c_str(), Describe("on the frame", frame).c_str());
  ASSERT_GT(head.of, 1000) << "the head fills the view";
  EXPECT_EQ(frame.in, 0) << Describe("first hits on the frame", frame);
  EXPECT_GE(head.Fraction(), 0.97) << Describe("first hits on the head", head);
  // Without the crop the frame stands in front of the face: the phantom
  // tests something.
  scene.clear_clipping();
  EXPECT_GT(ShareIn(Render(truth.image, scene, 64), truth, kFrame).in, 20) << "the frame is in view uncropped";
}

// A micro-CT of a mouse: a body of soft tissue with a skeleton (spine,
// ribs, skull, limb bones) three times as bright, in air, 0.25 mm voxels.
TruthVolume MicroCtMouse() {
  const Vec3i d{112, 64, 64};
  const float mm = 0.25f;
  const Phantom p = Build(d, mm, [](Vec3f c) -> std::pair<float, Tissue> {
    if (EllipsoidRadius(c, {13, 6.5f, 6.5f}) > 1.0f) return {12, kNone};
    const bool spine = Length(Vec3f{0, c.y - 3.0f, c.z}) < 0.9f && std::abs(c.x) < 10.0f;
    const float rib_r = Length(Vec3f{0, c.y - 1.0f, c.z});
    const bool ribs = std::abs(c.x + 1.0f) < 5.0f && std::fmod(std::abs(c.x) + 0.1f, 1.6f) < 0.5f &&
                      rib_r > 4.0f && rib_r < 4.7f && c.y < 3.0f;
    const bool skull = c.x > 9.0f && EllipsoidRadius(c - Vec3f{11.0f, 0, 0}, {3.2f, 4.0f, 4.0f}) < 1.0f &&
                       EllipsoidRadius(c - Vec3f{11.0f, 0, 0}, {2.6f, 3.4f, 3.4f}) > 1.0f;
    const bool legs = (std::abs(std::abs(c.z) - 3.5f) < 0.6f) && std::abs(c.y + 3.0f) < 0.6f &&
                      std::abs(std::abs(c.x) - 7.0f) < 2.5f;
    if (spine || ribs || skull || legs) return {200, kSkeleton};
    return {60, kBody};
  });
  std::mt19937 rng(11);
  std::vector<float> values = Blurred(p.values, d);
  for (float& v : values) v = std::clamp(v + Noise(rng, 6.0f), 0.0f, 255.0f);
  VolumeMetadata meta;
  meta.source = "phantom micro-CT mouse";
  TruthVolume t;
  t.image = std::make_shared<const Volume>(d, Vec3f{mm, mm, mm}, std::move(values), meta);
  t.tissue = p.tissue;
  return t;
}

TEST(PresetTissue, TheMicroCtDefaultShowsTheSkeleton) {
  const TruthVolume truth = MicroCtMouse();
  ASSERT_EQ(JudgeVolumeKind(*truth.image).kind, v1::OTHER);
  const ValueWindow w = AutoWindow(*truth.image);
  EXPECT_FALSE(std::isnan(w.dense)) << "the skeleton is a phase of its own";
  const Frame f = Render(truth.image, PresetScene(*truth.image, DefaultPreset(*truth.image)), 64);
  const Share skeleton = ShareIn(f, truth, kSkeleton);
  std::printf("%s\n", Describe("first hits on the skeleton", skeleton).c_str());
  ASSERT_GT(skeleton.of, 150);
  EXPECT_GE(skeleton.Fraction(), 0.8) << Describe("first hits on the skeleton", skeleton);
}

// --- The translation of Slicer's opacity -------------------------------------

// Slicer's opacity a at a point is what one millimetre of that tissue takes
// from the light: a slab 1 mm thick transmits 1 - a, between points too.
TEST(SlicerTranslation, AnOpacityIsWhatOneMillimetreTakes) {
  const TransferFunction aaa = ResolveTransferFunction(MakePreset("ct-aaa", ValueWindow{-1024, 3071}), Volume(
      {2, 2, 2}, {1, 1, 1}, std::vector<float>(8, 0.0f), {}));
  auto transmitted = [&](float hu) { return std::exp(-Evaluate(aaa, hu).opacity * aaa.density_scale * 1.0f); };
  EXPECT_NEAR(transmitted(166.222f), 1 - 0.686, 0.003);
  EXPECT_NEAR(transmitted(419.736f), 1 - 0.833, 0.003);
  // Between points VTK interpolates the opacity: halfway up 143.6..166.2 HU,
  // a = 0.343.
  EXPECT_NEAR(transmitted(154.889f), 1 - 0.343, 0.02);
  const TransferFunction lung = ResolveTransferFunction(MakePreset("ct-lung", ValueWindow{}), Volume(
      {2, 2, 2}, {1, 1, 1}, std::vector<float>(8, 0.0f), {}));
  EXPECT_NEAR(std::exp(-Evaluate(lung, -500).opacity * lung.density_scale), 0.85, 0.003);
  EXPECT_EQ(Evaluate(lung, 40).opacity, 0) << "soft tissue is clear in the lung preset";
}

}  // namespace
}  // namespace cinevol::testing

// Reading slices (issue 36), analytic: phantoms whose slices are known
// exactly: the VOI LINEAR grey levels, a sphere's radius on an oblique
// plane, a slab's maximum, the radiological convention and its letters for
// LPS, RAS and left-handed volumes, interpolation, labels and clipping.
#include "reading/slice.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>

#include "core/error.h"
#include "reading/orientation.h"
#include "reading/window_level.h"
#include "scene/scene_builder.h"

namespace cinevol {
namespace {

constexpr std::array<double, 9> kLps{1, 0, 0, 0, 1, 0, 0, 0, 1};
constexpr std::array<double, 9> kRas{-1, 0, 0, 0, -1, 0, 0, 0, 1};
constexpr std::array<double, 9> kLpi{1, 0, 0, 0, 1, 0, 0, 0, -1};  // left-handed: held mirrored

// A volume whose voxel values are `value(lps)` at each voxel centre.
Volume PatientPhantom(Vec3i dims, Vec3f spacing, std::array<double, 9> direction, std::array<double, 3> origin,
                      const std::function<float(Vec3f)>& value) {
  VolumeMetadata meta;
  meta.direction = direction;
  meta.origin_mm = origin;
  std::vector<float> values;
  for (int z = 0; z < dims.z; ++z) {
    for (int y = 0; y < dims.y; ++y) {
      for (int x = 0; x < dims.x; ++x) {
        const Vec3f i = Vec3f{float(x), float(y), float(z)} * spacing;
        Vec3f lps{float(origin[0]), float(origin[1]), float(origin[2])};
        for (int r = 0; r < 3; ++r)
          lps[r] += float(direction[3 * r] * i.x + direction[3 * r + 1] * i.y + direction[3 * r + 2] * i.z);
        values.push_back(value(lps));
      }
    }
  }
  return Volume(dims, spacing, std::move(values), meta);
}

// 32^3 voxels of 1 mm, LPS, voxel (x, y, z) at LPS (x, y, z) mm.
Volume IndexPhantom(const std::function<float(Vec3f)>& value) {
  return PatientPhantom({32, 32, 32}, {1, 1, 1}, kLps, {0, 0, 0}, value);
}

bool Within(Vec3f p, Vec3f lo, Vec3f hi) {
  return p.x >= lo.x && p.y >= lo.y && p.z >= lo.z && p.x <= hi.x && p.y <= hi.y && p.z <= hi.z;
}

const std::uint8_t* PixelAt(const SliceImage& slice, int column, int row) {
  return slice.image.bytes.data() + 3 * (std::size_t(row) * slice.image.width + column);
}
int GreyAt(const SliceImage& slice, int column, int row) { return PixelAt(slice, column, row)[0]; }

int CountAtLeast(const SliceImage& slice, int grey) {
  int n = 0;
  for (int r = 0; r < slice.image.height; ++r) {
    for (int c = 0; c < slice.image.width; ++c) n += GreyAt(slice, c, r) >= grey;
  }
  return n;
}

// Any value above 500 white, the rest black (VOI LINEAR with width 1).
constexpr VoiWindow kThreshold500{500.5, 1};

SliceSpec Axial(float z_mm, VoiWindow window = kThreshold500) {
  SliceSpec spec;
  spec.axis = SliceAxis::kAxial;
  spec.position_mm = z_mm;
  spec.window = window;
  return spec;
}

TEST(WindowLevel, VoiLinearFollowsTheStandardsThreeBranches) {
  const VoiWindow brain{40, 80};  // the ramp runs over (0, 79]
  EXPECT_EQ(ApplyVoiLinear(-1000, brain), 0);
  EXPECT_EQ(ApplyVoiLinear(0, brain), 0) << "x <= c - 0.5 - (w-1)/2 is the lower clamp, edge included";
  EXPECT_EQ(ApplyVoiLinear(39.5, brain), 128) << "c - 0.5 is the ramp's middle: 127.5, rounded up";
  EXPECT_EQ(ApplyVoiLinear(40, brain), 129);    // 129.11
  EXPECT_EQ(ApplyVoiLinear(50, brain), 161);    // 161.39
  EXPECT_EQ(ApplyVoiLinear(78.9, brain), 255);  // 254.68
  EXPECT_EQ(ApplyVoiLinear(79, brain), 255) << "the ramp's top edge is on the ramp";
  EXPECT_EQ(ApplyVoiLinear(3000, brain), 255);
  const VoiWindow lung = *FindWindowPreset("lung");
  EXPECT_EQ(lung.center, -600);
  EXPECT_EQ(lung.width, 1500);
  EXPECT_EQ(ApplyVoiLinear(-600, lung), 128);  // 127.59
  EXPECT_EQ(ApplyVoiLinear(0, lung), 230);     // 229.65
  EXPECT_EQ(FindWindowPreset("brain")->width, 80);
  EXPECT_EQ(FindWindowPreset("soft-tissue")->center, 50);
  EXPECT_EQ(FindWindowPreset("bone")->width, 1000);
  EXPECT_FALSE(FindWindowPreset("liver"));
}

TEST(WindowLevel, AutoWindowSpansTheSubjectNotTheBackground) {
  // An MR-like volume: background 0 around a subject of 4096 values spread evenly over 100..300.
  const Volume mr = IndexPhantom([](Vec3f p) {
    const float rank = (p.x - 8) * 256 + (p.y - 8) * 16 + (p.z - 8);
    return Within(p, {8, 8, 8}, {23, 23, 23}) ? 100.0f + 200.0f * rank / 4095 : 0.0f;
  });
  const VoiWindow w = AutoVoiWindow(mr.histogram());
  EXPECT_NEAR(w.center - 0.5 - (w.width - 1) / 2, 100, 10) << "the window starts near the subject's lowest values";
  EXPECT_NEAR(w.center - 0.5 + (w.width - 1) / 2, 300, 10) << "and ends near its highest";
  std::string name;
  DefaultWindow(mr, &name);
  EXPECT_EQ(name, "auto") << "no HU: the automatic window";
}

// The window a DICOM stores is a choice of its own, and the default.
TEST(WindowLevel, TheStoredWindowIsChosenByNameAndByDefault) {
  VolumeMetadata meta;
  meta.value_unit = "HU";
  meta.stored_window = VoiWindow{268, 622};
  const Volume dicom({4, 4, 4}, {1, 1, 1}, std::vector<float>(64, 0.0f), meta);
  EXPECT_EQ(WindowNamed("stored", dicom).width, 622);
  EXPECT_EQ(WindowNamed("", dicom).center, 268) << "the DICOM's window first";
  EXPECT_EQ(WindowNamed("lung", dicom).center, -600);
  std::string name;
  DefaultWindow(dicom, &name);
  EXPECT_EQ(name, "stored");
  meta.stored_window.reset();
  const Volume other({4, 4, 4}, {1, 1, 1}, std::vector<float>(64, 0.0f), meta);
  EXPECT_EQ(WindowNamed("", other).center, 50) << "soft tissue for HU";
  EXPECT_THROW(WindowNamed("stored", other), InputError);
  EXPECT_THROW(WindowNamed("liver", other), InputError);
}

// Cubes of known values in air, each through the brain window: the centre
// pixel's grey is the formula's, for 16-bit and float storage alike.
TEST(Slice, APhantomCubeThroughAWindowGivesTheFormulasGreyLevels) {
  const VoiWindow brain{40, 80};
  const std::pair<float, int> value_grey[] = {{-1000, 0}, {0, 0},    {39.5f, 128}, {40, 129},
                                              {50, 161},  {79, 255}, {500, 255}};
  for (const auto& [value, grey] : value_grey) {
    const Volume cube = IndexPhantom([v = value](Vec3f p) { return Within(p, {8, 8, 8}, {23, 23, 23}) ? v : -1000; });
    for (bool nearest : {false, true}) {
      SliceSpec spec = Axial(15, brain);
      spec.nearest = nearest;
      const SliceImage slice = RenderSlice(cube, {}, nullptr, spec);
      EXPECT_EQ(GreyAt(slice, 15, 15), grey) << "value " << value << (nearest ? " nearest" : " linear");
      EXPECT_EQ(GreyAt(slice, 2, 2), 0) << "air";
    }
  }
}

// One pixel per voxel: pixel (i, j) of an axial slice on plane k is voxel
// (i, j, k) of an LPS volume, at its position exactly.
TEST(Slice, AnAxialSliceIsTheVoxelGridAtItsOwnSpacing) {
  const Volume volume = PatientPhantom({20, 24, 10}, {0.7f, 0.9f, 2.5f}, kLps, {-7, -10, 30}, [](Vec3f p) {
    return std::fmod(std::abs(p.x * 37 + p.y * 11 + p.z * 3), 200.0f) - 100;
  });
  const SliceSpec spec = Axial(30 + 4 * 2.5f, {0, 200});
  const SliceImage slice = RenderSlice(volume, {}, nullptr, spec);
  ASSERT_EQ(slice.image.width, 20);
  ASSERT_EQ(slice.image.height, 24);
  EXPECT_FLOAT_EQ(slice.geometry.pixel_width_mm, 0.7f);
  EXPECT_FLOAT_EQ(slice.geometry.pixel_height_mm, 0.9f);
  for (int j = 0; j < 24; ++j) {
    for (int i = 0; i < 20; ++i) {
      ASSERT_EQ(GreyAt(slice, i, j), ApplyVoiLinear(volume.Value(i, j, 4), spec.window)) << i << "," << j;
      const Vec3f at = slice.geometry.PixelToPatient(float(i), float(j));
      ASSERT_NEAR(at.x, -7 + 0.7f * i, 1e-4f);
      ASSERT_NEAR(at.y, -10 + 0.9f * j, 1e-4f);
      ASSERT_NEAR(at.z, 40, 1e-4f);
    }
  }
}

// A ball of radius 20 mm on an anisotropic grid, cut through its centre by
// an oblique plane: the disc's area gives its radius within a pixel.
TEST(Slice, AnObliqueSliceOfASphereHasItsRadius) {
  const Vec3f centre{10, -5, 40};
  constexpr float kRadius = 20;
  const Volume ball = PatientPhantom({80, 80, 40}, {0.8f, 0.8f, 1.6f}, kLps, {-22, -37, 8},
                                     [&](Vec3f p) { return Length(p - centre) <= kRadius ? 1000.0f : 0.0f; });
  SliceSpec spec;
  spec.axis = SliceAxis::kOblique;
  spec.point_lps = centre;
  spec.normal_lps = {1, 1, 1};
  spec.row_lps = {1, -1, 0};
  spec.window = kThreshold500;
  const SliceImage slice = RenderSlice(ball, {}, nullptr, spec);
  EXPECT_FLOAT_EQ(slice.geometry.pixel_width_mm, 0.8f) << "the smallest spacing";
  const float pixel_area = slice.geometry.pixel_width_mm * slice.geometry.pixel_height_mm;
  const float radius = std::sqrt(float(CountAtLeast(slice, 255)) * pixel_area / float(M_PI));
  EXPECT_NEAR(radius, kRadius, slice.geometry.pixel_width_mm);
  // The plane passes through the centre: some pixel's position is within half a pixel of it.
  const Vec3f normal = Normalize(Vec3f{1, 1, 1});
  EXPECT_NEAR(Dot(slice.geometry.PixelToPatient(3, 7) - centre, normal), 0, 1e-3f);
  EXPECT_NEAR(Dot(slice.geometry.normal, normal), 1, 1e-5f);
}

// Two cubes at different heights: a thin slice through one shows it alone;
// a 12 mm slab between them shows both by its maximum, neither by its minimum.
TEST(Slice, ASlabMipOfTwoOffsetCubesShowsBothAThinSliceOne) {
  const Volume cubes = IndexPhantom([](Vec3f p) {
    const bool low = Within(p, {4, 12, 8}, {11, 19, 11}), high = Within(p, {20, 12, 16}, {27, 19, 19});
    return low || high ? 1000.0f : 0.0f;
  });
  const SliceImage thin = RenderSlice(cubes, {}, nullptr, Axial(10));
  EXPECT_EQ(GreyAt(thin, 8, 15), 255);
  EXPECT_EQ(GreyAt(thin, 24, 15), 0);
  SliceSpec slab = Axial(14);
  slab.slab_mm = 12;  // samples at z 8..20
  EXPECT_EQ(GreyAt(RenderSlice(cubes, {}, nullptr, slab), 8, 15), 255);
  EXPECT_EQ(GreyAt(RenderSlice(cubes, {}, nullptr, slab), 24, 15), 255);
  EXPECT_EQ(CountAtLeast(RenderSlice(cubes, {}, nullptr, slab), 255), 2 * 8 * 8);
  slab.projection = SlabProjection::kMin;
  EXPECT_EQ(CountAtLeast(RenderSlice(cubes, {}, nullptr, slab), 1), 0);
  slab.projection = SlabProjection::kMean;  // 4 of 13 samples in a cube: 307.7
  slab.window = {500.5, 1001};              // grey = value * 255 / 1000
  EXPECT_EQ(GreyAt(RenderSlice(cubes, {}, nullptr, slab), 8, 15), 78);
  EXPECT_FLOAT_EQ(SlabStep(cubes, {0, 0, 1}), 1.0f);
}

// The brightest pixels' centre (column, row).
Vec3f BrightCentroid(const SliceImage& slice, int from_column, int to_column, int from_row, int to_row) {
  Vec3f sum;
  float n = 0;
  for (int r = from_row; r < to_row; ++r) {
    for (int c = from_column; c < to_column; ++c) {
      if (GreyAt(slice, c, r) == 255) sum += Vec3f{float(c), float(r), 0}, ++n;
    }
  }
  return sum / std::max(n, 1.0f);
}

// A caller gone: a raised flag stops the slab at once, with Cancelled.
TEST(Slice, ARaisedCancelFlagStopsTheSlice) {
  const Volume cubes = IndexPhantom([](Vec3f) { return 0.0f; });
  SliceSpec slab = Axial(14);
  slab.slab_mm = 12;
  std::atomic<bool> cancel{true};
  EXPECT_THROW(RenderSlice(cubes, {}, nullptr, slab, &cancel), Cancelled);
  cancel = false;
  EXPECT_NO_THROW(RenderSlice(cubes, {}, nullptr, slab, &cancel));
}

// The same patient stored three ways: a marker on the patient's left, one
// anterior and one superior. Every axial slice shows the left one on the
// image's right and the anterior one at the top, with R|L and A|P at the edges.
TEST(Slice, AxialSlicesAreRadiologicalForLpsRasAndLeftHandedVolumes) {
  auto patient = [](Vec3f p) {
    const bool left = Within(p, {8, -2, -2}, {14, 2, 2}), anterior = Within(p, {-2, -14, -2}, {2, -8, 2});
    return left || anterior ? 1000.0f : 0.0f;
  };
  const Volume lps = PatientPhantom({32, 32, 32}, {1, 1, 1}, kLps, {-15.5, -15.5, -15.5}, patient);
  const Volume ras = PatientPhantom({32, 32, 32}, {1, 1, 1}, kRas, {15.5, 15.5, -15.5}, patient);
  const Volume lpi = PatientPhantom({32, 32, 32}, {1, 1, 1}, kLpi, {-15.5, -15.5, 15.5}, patient);
  const SliceImage reference = RenderSlice(lps, {}, nullptr, Axial(0.5f));
  for (const Volume* volume : {&lps, &ras, &lpi}) {
    const SliceImage slice = RenderSlice(*volume, {}, nullptr, Axial(0.5f));
    const std::string code = OrientationCode(volume->metadata().direction);
    EXPECT_EQ(slice.image.bytes, reference.image.bytes) << code << ": the same patient, the same slice";
    const Vec3f left = BrightCentroid(slice, 0, 32, 12, 20), anterior = BrightCentroid(slice, 12, 20, 0, 32);
    EXPECT_GT(left.x, 20) << code << ": the patient's left on the image's right";
    EXPECT_LT(anterior.y, 12) << code << ": anterior at the top";
    EXPECT_NEAR(slice.geometry.PixelToPatient(left.x, left.y).x, 11, 0.01f) << code;
    const EdgeLetters& e = slice.geometry.letters;
    EXPECT_EQ(e.left + e.right + e.top + e.bottom, "RLAP") << code;
  }
}

TEST(Slice, CoronalAndSagittalSlicesCarryTheirLetters) {
  const Volume ras = PatientPhantom({16, 16, 16}, {1, 1, 1}, kRas, {7.5, 7.5, -7.5}, [](Vec3f) { return 0.0f; });
  SliceSpec spec = Axial(0.5f);
  spec.axis = SliceAxis::kCoronal;
  EdgeLetters e = RenderSlice(ras, {}, nullptr, spec).geometry.letters;
  EXPECT_EQ(e.left + e.right + e.top + e.bottom, "RLSI");
  spec.axis = SliceAxis::kSagittal;
  e = RenderSlice(ras, {}, nullptr, spec).geometry.letters;
  EXPECT_EQ(e.left + e.right + e.top + e.bottom, "APSI");
  const PositionRange range = SlicePositionRange(ras, SliceAxis::kSagittal);
  EXPECT_FLOAT_EQ(range.lo, -7.5f);
  EXPECT_FLOAT_EQ(range.hi, 7.5f);
}

TEST(Orientation, LettersNameTheDominantAxisThenAnObliqueOne) {
  EXPECT_EQ(OrientationLetters({1, 0, 0}), "L");
  EXPECT_EQ(OrientationLetters({0, -3, 0}), "A");
  EXPECT_EQ(OrientationLetters({0, 0, -1}), "I");
  EXPECT_EQ(OrientationLetters({0.9f, 0.4f, 0}), "LP");
  EXPECT_EQ(OrientationLetters({-0.3f, 0, 0.95f}), "SR");
  EXPECT_EQ(OrientationLetters({0.99f, 0.1f, 0}), "L") << "a few degrees off reads straight";
  EXPECT_EQ(OrientationLetters({0, 0, 0}), "");
  EXPECT_EQ(OrientationLetters(IndexAxisDirection(kRas, 0)), "R");
}

// A sharp step between two slices, cut a quarter of the way across: linear
// interpolation blends the two, nearest takes the closer one.
TEST(Slice, NearestAndLinearDifferAtABoundary) {
  const Volume step = IndexPhantom([](Vec3f p) { return p.z >= 16 ? 1000.0f : 0.0f; });
  SliceSpec spec = Axial(15.25f, {500.5, 1000});
  EXPECT_EQ(GreyAt(RenderSlice(step, {}, nullptr, spec), 10, 10), ApplyVoiLinear(250, spec.window));
  spec.nearest = true;
  EXPECT_EQ(GreyAt(RenderSlice(step, {}, nullptr, spec), 10, 10), 0);
}

// Labels 1 (red) and 2 on a black image: label 1 is painted at half
// opacity, label 2 not while hidden, in the palette without a style.
TEST(Slice, TheLabelOverlayPaintsShownLabelsOnly) {
  const Volume air = IndexPhantom([](Vec3f) { return -1000.0f; });
  LabelVolume labels;
  labels.dims = air.dims();
  labels.labels.assign(air.voxel_count(), 0);
  for (int y = 4; y < 8; ++y) {
    for (int x = 4; x < 8; ++x) labels.labels[(std::size_t(15) * 32 + y) * 32 + x] = 1;
  }
  for (int y = 20; y < 24; ++y) {
    for (int x = 20; x < 24; ++x) labels.labels[(std::size_t(15) * 32 + y) * 32 + x] = 2;
  }
  labels.voxels = {{1, 16}, {2, 16}};
  LabelSetup setup;
  setup.styles[1].has_color = true;
  setup.styles[1].color = {1, 0, 0};
  setup.styles[2].visible = false;
  const SliceImage styled = RenderSlice(air, {&labels, &setup}, nullptr, Axial(15));
  EXPECT_EQ(std::vector<int>(PixelAt(styled, 5, 5), PixelAt(styled, 5, 5) + 3), (std::vector<int>{128, 0, 0}));
  EXPECT_EQ(GreyAt(styled, 21, 21) + PixelAt(styled, 21, 21)[1], 0) << "label 2 is hidden";
  EXPECT_EQ(GreyAt(styled, 12, 12), 0) << "unlabelled";
  const SliceImage palette = RenderSlice(air, {&labels, nullptr}, nullptr, Axial(15));
  EXPECT_GT(PixelAt(palette, 21, 21)[0], 100) << "without a style, label 2 takes the palette's second colour";
  EXPECT_EQ(GreyAt(RenderSlice(air, {&labels, &setup}, nullptr, Axial(20)), 5, 5), 0) << "another plane";
}

// A clip plane keeping the patient's left: the right half goes black when
// clipping is shown, and nothing changes when it is ignored.
TEST(Slice, ClippingBlacksOutTheCutSide) {
  const Volume solid =
      PatientPhantom({32, 32, 32}, {1, 1, 1}, kRas, {15.5, 15.5, -15.5}, [](Vec3f) { return 1000.0f; });
  v1::Clipping clipping;
  clipping.add_planes()->mutable_normal()->set_x(1);  // through LPS 0, keeping x >= 0
  const ClipRegion clip = ResolveClipping(clipping, solid);
  const SliceImage cut = RenderSlice(solid, {}, &clip, Axial(0.5f));
  EXPECT_EQ(GreyAt(cut, 5, 16), 0) << "the patient's right, on the image's left: cut away";
  EXPECT_EQ(GreyAt(cut, 26, 16), 255) << "the patient's left: kept";
  EXPECT_EQ(CountAtLeast(cut, 255), 16 * 32);
  EXPECT_EQ(CountAtLeast(RenderSlice(solid, {}, nullptr, Axial(0.5f)), 255), 32 * 32);
}

TEST(Slice, BadSpecsAreRefused) {
  const Volume air = IndexPhantom([](Vec3f) { return 0.0f; });
  EXPECT_THROW(RenderSlice(air, {}, nullptr, Axial(3, {0, 0.5})), InputError);
  SliceSpec spec = Axial(3);
  spec.axis = SliceAxis::kOblique;
  spec.row_lps = spec.normal_lps;
  EXPECT_THROW(RenderSlice(air, {}, nullptr, spec), InputError);
  // Found by fuzz_requests: a position past float's range made an infinite span, and its pixel count no int.
  for (float far : {INFINITY, -1e30f, 2e9f}) {
    spec = Axial(3);
    spec.position_mm = far;
    EXPECT_THROW(PlanSlice(air, spec), InputError) << far;
    spec = Axial(3);
    spec.axis = SliceAxis::kOblique;
    spec.point_lps = {0, far, 0};
    EXPECT_THROW(PlanSlice(air, spec), InputError) << far;
    spec.point_lps = {};
    spec.normal_lps = {far, 1, 0};  // a length that overflows
    if (std::isinf(Length(spec.normal_lps))) {
      EXPECT_THROW(PlanSlice(air, spec), InputError) << far;
    }
  }
}

// Whatever the plane asks, a slice is what a screen shows: at most
// kMaxSliceSide pixels a side and kMaxSliceSamples samples.
TEST(Slice, APlaneOfAnySizeOrSlabIsBoundedByTheScreen) {
  const Volume air = IndexPhantom([](Vec3f) { return 0.0f; });
  SliceSpec spec = Axial(3);
  spec.axis = SliceAxis::kOblique;
  spec.normal_lps = {1, 1, 1};
  spec.pixel_mm = 1e-4f;
  spec.slab_mm = 1e4f;
  const SliceGeometry g = PlanSlice(air, spec);
  EXPECT_EQ(std::max(g.width, g.height), kMaxSliceSide);
  EXPECT_NEAR(g.pixel_width_mm / g.pixel_height_mm, 1.0f, 1e-6f) << "pixels grow alike both ways";
  EXPECT_LE(static_cast<long long>(g.width) * g.height * (2 * g.slab_half + 1), kMaxSliceSamples);
  EXPECT_GT(g.slab_half, 0);
  EXPECT_GT(g.slab_step_mm, SlabStep(air, g.normal)) << "the slab's samples spread";
}

// A slice on a grid of its own (a DICOM frame's): its pixels where the grid
// says, beyond the volume black, its size whatever the volume's projection.
TEST(Slice, AGridOfItsOwnSamplesWhereItSaysNotTheVolumesProjection) {
  const Volume volume = PatientPhantom({20, 24, 10}, {0.7f, 0.9f, 2.5f}, kLps, {-7, -10, 30}, [](Vec3f p) {
    return std::fmod(std::abs(p.x * 37 + p.y * 11 + p.z * 3), 200.0f) - 100;
  });
  SliceSpec spec = Axial(0, {0, 200});
  spec.axis = SliceAxis::kOblique;
  spec.point_lps = {-7 + 0.7f * 3, -10 + 0.9f * 5, 30 + 2.5f * 4};  // voxel (3, 5, 4)
  spec.grid = SliceSpec::Grid{30, 7, 0.7f, 0.9f};
  const SliceImage slice = RenderSlice(volume, {}, nullptr, spec);
  ASSERT_EQ(slice.image.width, 30);
  ASSERT_EQ(slice.image.height, 7);
  for (int j = 0; j < 7; ++j) {
    for (int i = 0; i < 30; ++i) {
      const int expected = 3 + i < 20 ? ApplyVoiLinear(volume.Value(3 + i, 5 + j, 4), spec.window) : 0;
      ASSERT_EQ(GreyAt(slice, i, j), expected) << i << "," << j;
    }
  }
  for (SliceSpec::Grid bad : {SliceSpec::Grid{0, 7, 1, 1}, SliceSpec::Grid{kMaxSliceSide + 1, 7, 1, 1},
                              SliceSpec::Grid{30, 7, 0, 1}, SliceSpec::Grid{30, 7, 1, NAN}}) {
    spec.grid = bad;
    EXPECT_THROW(PlanSlice(volume, spec), InputError) << bad.width << " " << bad.pixel_width_mm;
  }
  spec.grid = SliceSpec::Grid{30, 7, 0.7f, 0.9f};
  spec.axis = SliceAxis::kAxial;
  EXPECT_THROW(PlanSlice(volume, spec), InputError) << "a grid is an oblique plane's";
}

}  // namespace
}  // namespace cinevol

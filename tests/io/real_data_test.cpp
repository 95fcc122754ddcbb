// Every loader on the real data sets, checked against their READMEs.
#include <gtest/gtest.h>

#include "io/volume_loader.h"
#include "support/test_paths.h"

namespace cinevol {
namespace {

using testing::SharedData;

struct Expected {
  const char* path;  // under ../shared/data
  Vec3i dims;
  Vec3f spacing;
  float min_value, max_value;  // NaN: not stated in the README
  const char* modality;
};

void PrintTo(const Expected& e, std::ostream* os) { *os << e.path; }

class RealData : public ::testing::TestWithParam<Expected> {};

TEST_P(RealData, MatchesItsReadme) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const Expected& e = GetParam();
  const Volume v = LoadVolume(ParseVolumeSpec((SharedData() / e.path).string()));
  EXPECT_EQ(v.dims(), e.dims);
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(v.spacing_mm()[a], e.spacing[a], 1e-3f) << "axis " << a;
  if (!std::isnan(e.min_value)) {
    EXPECT_NEAR(v.min_value(), e.min_value, 1e-2f * std::max(1.0f, std::abs(e.min_value)));
    EXPECT_NEAR(v.max_value(), e.max_value, 1e-2f * std::max(1.0f, std::abs(e.max_value)));
  }
  EXPECT_EQ(v.metadata().modality, e.modality);
  EXPECT_EQ(v.metadata().non_finite_replaced, 0u);
}

constexpr float kUnstated = NAN;

INSTANTIATE_TEST_SUITE_P(
    SharedData, RealData,
    ::testing::Values(
        // NRRD detached headers: one over big-endian slices, one whose header
        // mixes `space` with `spacings`, one over gzip raw.
        Expected{"ct-head-cthead/DERIVED_CThead.nhdr", {256, 256, 113}, {1, 1, 2}, 0, 3272, ""},
        Expected{"ct-head-headsq/quarter.nhdr", {64, 64, 93}, {3.2f, 3.2f, 1.5f}, 0, 3926, ""},
        Expected{"ct-chest-lidc2/LIDC2.nhdr", {256, 256, 133}, {1.40625f, 1.40625f, 2.5f}, 0, 255, ""},
        // NIfTI: uint8 with scl_slope, int16 and int32 HU.
        Expected{"ct-head-avm/AVM.nii.gz", {337, 319, 154}, {0.5469f, 0.5469f, 1}, 0, 255 * 2.20863f, ""},
        Expected{"ct-head-avm/CT_AVM.nii.gz", {256, 242, 154}, {0.72f, 0.72f, 1}, kUnstated, 0, ""},
        Expected{
            "ct-body-totalsegmentator/aorta_ct_cropped.nii.gz", {120, 126, 164}, {1.5f, 1.5f, 1.5f}, -1078, 3343, ""},
        Expected{"ct-body-totalsegmentator/pulmonary_ct_cropped.nii.gz",
                 {122, 102, 112},
                 {1.5f, 1.5f, 1.5f},
                 -1064,
                 3343,
                 ""},
        Expected{"ct-body-totalsegmentator/example_ct.nii.gz", {122, 101, 112}, {3, 3, 3}, -1207, 3382, ""},
        Expected{"mr-head-seg3d-nifti/MR.nii.gz", {160, 232, 160}, {1, 0.8984f, 0.8984f}, kUnstated, 0, ""},
        Expected{"ct-objects-openscivis/bonsai.nii.gz", {256, 256, 256}, {1, 1, 1}, kUnstated, 0, ""},
        Expected{"ct-objects-openscivis/engine.nii.gz", {256, 256, 128}, {1, 1, 1}, kUnstated, 0, ""},
        // DICOM series: JPEG 2000 lossless CT with intercept -1024; plain MR.
        Expected{
            "ct-body-totalsegmentator/example_ct_dicom", {512, 512, 20}, {0.9766f, 0.9766f, 2}, kUnstated, 0, "CT"},
        Expected{"mr-chest-dicom-seg3d", {640, 640, 20}, {0.625f, 0.625f, 2.5f}, kUnstated, 0, "MR"}),
    [](const auto& info) {
      std::string name = info.param.path;
      name = name.substr(0, name.find_first_of("./", name.find('/') + 1));
      for (char& c : name) {
        if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
      }
      return name;
    });

TEST(RealDicom, CtIsRescaledToHounsfieldUnits) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const Volume v = LoadVolume(ParseVolumeSpec((SharedData() / "ct-body-totalsegmentator/example_ct_dicom").string()));
  EXPECT_EQ(v.metadata().value_unit, "HU");
  // Air outside the patient after intercept -1024.
  EXPECT_EQ(v.min_value(), -1024.0f);
  EXPECT_EQ(v.Value(0, 0, 0), -1024.0f);
  EXPECT_GT(v.max_value(), 1000.0f);  // bone
}

// A CT in HU from a format with no field for its unit (NIfTI) reads in HU
// as the DICOM does, saying why; an MR does not.
TEST(RealNifti, ACtJudgedInHuReadsInHu) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const Volume ct = LoadVolume(ParseVolumeSpec((SharedData() / "ct-body-totalsegmentator/example_ct.nii.gz").string()));
  EXPECT_EQ(ct.metadata().value_unit, "HU");
  ASSERT_FALSE(ct.metadata().notes.empty());
  EXPECT_EQ(ct.metadata().notes.back().rfind("values taken as HU: ", 0), 0u) << ct.metadata().notes.back();
  const Volume mr = LoadVolume(ParseVolumeSpec((SharedData() / "mr-head-seg3d-nifti/MR.nii.gz").string()));
  EXPECT_EQ(mr.metadata().value_unit, "");
}

TEST(RealDicom, SlicesAreSortedAlongTheNormal) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const Volume v = LoadVolume(ParseVolumeSpec((SharedData() / "mr-chest-dicom-seg3d").string()));
  // The origin is the first slice along the normal, and index z runs along it.
  const auto& m = v.metadata();
  EXPECT_NEAR(m.direction[8], 1.0, 1e-6);  // normal is +z (superior)
  EXPECT_NEAR(m.origin_mm[2], 12.8795, 1e-3);
}

TEST(RealNifti, KeepsPatientOrientation) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const Volume v = LoadVolume(ParseVolumeSpec((SharedData() / "ct-head-avm/AVM.nii.gz").string()));
  // NIfTI's RAS storage arrives as LPS direction cosines diag(-1, -1, 1).
  EXPECT_NEAR(v.metadata().direction[0], -1.0, 1e-6);
  EXPECT_NEAR(v.metadata().direction[4], -1.0, 1e-6);
  EXPECT_NEAR(v.metadata().direction[8], 1.0, 1e-6);
  EXPECT_NE(v.metadata().original_type.find("uint8"), std::string::npos);
}

}  // namespace
}  // namespace cinevol

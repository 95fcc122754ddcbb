// Time series (issue 59) through the reader cage: a 4-D NIfTI's phases and
// times, each phase its own volume; every phase counted before any voxel is
// read; a series where one volume is read refused by name.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "core/error.h"
#include "io/volume_loader.h"
#include "support/error_of.h"
#include "support/test_paths.h"
#include "support/time_series_nifti.h"

namespace cinevol::testing {
namespace {

// The centre of the voxels above 500, along index x.
double CentreX(const Volume& v) {
  double sum = 0, count = 0;
  for (int z = 0; z < v.dims().z; ++z) {
    for (int y = 0; y < v.dims().y; ++y) {
      for (int x = 0; x < v.dims().x; ++x) {
        if (v.Value(x, y, z) > 500) sum += x, ++count;
      }
    }
  }
  return count > 0 ? sum / count : -1;
}

TEST(TimeSeries, A4dNiftiLoadsEveryPhaseWithItsTimes) {
  ScratchDir scratch;
  const auto file = scratch / "sphere.nii";
  WriteMovingSphere(file, {});
  v1::VolumeSource source;
  source.set_file(file.string());
  const VolumeSeries series = LoadVolumeSeries(source);
  ASSERT_EQ(series.phases.size(), 5u);
  ASSERT_EQ(series.seconds.size(), 5u);
  for (int k = 0; k < 5; ++k) {
    EXPECT_NEAR(series.seconds[k], 0.1 * k, 1e-6) << k;
    EXPECT_EQ(series.phases[k].dims(), (Vec3i{24, 24, 24}));
    EXPECT_NEAR(CentreX(series.phases[k]), 8 + k, 1e-9) << "the sphere moves a voxel a phase";
    EXPECT_EQ(series.phases[k].metadata().origin_mm, series.phases[0].metadata().origin_mm);
  }
  const std::string refused = ErrorOf<InputError>([&] { LoadVolume(source); });
  EXPECT_NE(refused.find("a time series of 5 phases"), std::string::npos) << refused;
}

// A header that claims 10^5 phases, or phases past the voxel limit, is refused
// before the reader's voxels are asked for, naming the count.
TEST(TimeSeries, SeriesPastTheLimitsAreRefusedBeforeAnyVoxel) {
  ScratchDir scratch;
  const auto lying = scratch / "lying.nii";
  WriteMovingSphere(lying, {.phases = 1, .header_phases = 30000});  // NIfTI-1 counts phases in 16 bits
  v1::VolumeSource source;
  source.set_file(lying.string());
  const std::string many = ErrorOf<InputError>([&] { LoadVolumeSeries(source); });
  EXPECT_NE(many.find("30000 phases"), std::string::npos) << many;

  const auto file = scratch / "sphere.nii";
  WriteMovingSphere(file, {});
  source.set_file(file.string());
  LoadPolicy policy;
  policy.max_voxels = 24 * 24 * 24 * 4;  // four phases' worth
  bool reserved = false;
  policy.reserve = [&](std::uint64_t) { reserved = true; };
  const std::string over = ErrorOf<InputError>([&] { LoadVolumeSeries(source, {}, policy); });
  EXPECT_NE(over.find("x 5 phases"), std::string::npos) << over;
  EXPECT_FALSE(reserved) << "refused from the header, before any memory";
  policy.max_voxels = 24 * 24 * 24 * 5;
  std::uint64_t bytes = 0;
  policy.reserve = [&](std::uint64_t b) { bytes += b; };
  EXPECT_EQ(LoadVolumeSeries(source, {}, policy).phases.size(), 5u);
  EXPECT_GE(bytes, 5u * 24 * 24 * 24 * 2) << "every phase's memory reserved at once";
}

}  // namespace
}  // namespace cinevol::testing

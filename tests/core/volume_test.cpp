#include "core/volume.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numeric>

#include "core/error.h"

namespace cinevol {
namespace {

VolumeMetadata Named(const char* source) {
  VolumeMetadata m;
  m.source = source;
  return m;
}

TEST(Volume, IntegerHuFitsSixteenBits) {
  Volume v({2, 1, 1}, {1, 1, 1}, {-1024.0f, 3071.0f}, Named("t"));
  EXPECT_EQ(v.storage(), VoxelStorage::kUInt16);
  EXPECT_EQ(v.Value(0, 0, 0), -1024.0f);
  EXPECT_EQ(v.Value(1, 0, 0), 3071.0f);
  // The voxels, one block's value range and the histogram.
  EXPECT_EQ(v.MemoryBytes(), 4u + sizeof(Volume::ValueRange) + ValueHistogram::kBins * sizeof(std::uint64_t));
}

TEST(Volume, FractionalOrWideValuesStayFloat) {
  EXPECT_EQ(Volume({2, 1, 1}, {1, 1, 1}, {0.5f, 1.0f}, Named("t")).storage(), VoxelStorage::kFloat32);
  EXPECT_EQ(Volume({2, 1, 1}, {1, 1, 1}, {0.0f, 70000.0f}, Named("t")).storage(), VoxelStorage::kFloat32);
}

TEST(Volume, NonFiniteVoxelsAreReplacedAndCounted) {
  const float inf = std::numeric_limits<float>::infinity();
  Volume v({4, 1, 1}, {1, 1, 1}, {std::nanf(""), -inf, inf, 7.0f}, Named("t"));
  v.metadata();
  EXPECT_EQ(v.metadata().non_finite_replaced, 3u);
  EXPECT_EQ(v.Value(0, 0, 0), 7.0f);
  EXPECT_EQ(v.Value(2, 0, 0), 7.0f);
}

TEST(Volume, RejectsBadGeometryNamingTheSource) {
  EXPECT_THROW(Volume({0, 1, 1}, {1, 1, 1}, {}, Named("t")), InputError);
  EXPECT_THROW(Volume({1, 1, 1}, {0, 1, 1}, {1.0f}, Named("t")), InputError);
  EXPECT_THROW(Volume({1, 1, 1}, {std::nanf(""), 1, 1}, {1.0f}, Named("t")), InputError);
  try {
    CheckVolumeGeometry({8192, 8192, 8192}, {1, 1, 1}, "huge.nii");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("huge.nii"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("exceeds the limit"), std::string::npos);
  }
}

TEST(Volume, RejectsValueCountMismatch) {
  EXPECT_THROW(Volume({2, 2, 1}, {1, 1, 1}, {1.0f, 2.0f}, Named("t")), InputError);
}

TEST(ValueHistogram, PercentilesAndTheThresholdBetweenTwoClasses) {
  // 3/4 of the voxels are background near 0, 1/4 subject spread over 600..1000.
  std::vector<float> values;
  for (int i = 0; i < 3000; ++i) values.push_back(float(i % 20));
  for (int i = 0; i < 1000; ++i) values.push_back(600.0f + 0.4f * float(i));
  const ValueHistogram h = ValueHistogram::Of(ValuesView<float>(values), 0.0f, 0.0f, 999.6f);
  EXPECT_EQ(std::accumulate(h.counts.begin(), h.counts.end(), std::uint64_t{0}), values.size());
  EXPECT_NEAR(h.Percentile(0.5), 13.0f, 8.0f);
  const float threshold = h.OtsuThreshold();
  EXPECT_GE(threshold, 19.0f);  // above every background value
  EXPECT_LE(threshold, 600.0f);
  EXPECT_NEAR(h.Percentile(0.5, threshold), 800.0f, 8.0f);  // the subject's median
  EXPECT_NEAR(h.Percentile(1.0, threshold), 999.6f, 4.0f);
}

TEST(ValueHistogram, ConstantVolumesHaveOneFullBin) {
  const Volume v({2, 2, 2}, {1, 1, 1}, std::vector<float>(8, 5.0f), Named("t"));
  EXPECT_EQ(v.histogram().counts[0], 8u);
  EXPECT_EQ(v.histogram().Percentile(0.5), 5.0f);
}

TEST(Volume, BlockRangesBoundEveryVoxel) {
  std::vector<float> values(20 * 9 * 3);
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = float(i % 37);
  const Volume v({20, 9, 3}, {1, 1, 1}, values, Named("t"));
  EXPECT_EQ(v.block_counts(), (Vec3i{5, 3, 1}));
  for (int z = 0; z < 3; ++z) {
    for (int y = 0; y < 9; ++y) {
      for (int x = 0; x < 20; ++x) {
        const auto r = v.block_ranges()[(y / 4) * 5 + x / 4];
        EXPECT_LE(r.lo, v.Value(x, y, z));
        EXPECT_GE(r.hi, v.Value(x, y, z));
      }
    }
  }
}

}  // namespace
}  // namespace cinevol
